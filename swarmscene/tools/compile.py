"""``swarmscene-compile``: compile every compiled kernel ahead, once per machine or image.

    swarmscene-compile            # or: python -m swarmscene.tools.compile

The engine's kernels (numba, ``cache=True``) are compiled the first time a run calls them and
kept in numba's on-disk cache; a fresh cluster node or container image otherwise pays that compile
in its first jobs (the tutorial's first CEM run: ~15 s). This command runs every preset briefly
with its events moved early, so that each method's kernels (CEM's after a failure, the indoor
rules, flocking, the quadrotor plant, the cell lists of large swarms) run once, a swarm over
the dense-pair limit on each dynamics model, and the ``swarmlab`` observer's compiled pass.
Nothing is written but numba's cache (its default place: ``__pycache__`` beside each module, or
the user's cache when that is read-only; ``NUMBA_CACHE_DIR`` moves it, e.g. onto a shared file
system or into the image).

A run that fails here is named in one line and the others go on; the exit status is 1 then.
"""

from __future__ import annotations

import argparse
import sys
import time


def warmups() -> list[tuple[str, list[str]]]:
    """(label, overrides) of the warm-up runs: every preset, large swarms on each dynamics, the swarmlab observer."""
    from importlib.resources import files

    folder = files("swarmscene.scenarios").joinpath("scenario")  # the installed presets, wheel or source tree
    presets = sorted(p.name.removesuffix(".yaml") for p in folder.iterdir() if p.name.endswith(".yaml"))
    runs = [(f"scenario={p}", [f"scenario={p}"]) for p in presets]
    for dynamics in ("single_integrator", "double_integrator", "quadrotor"):
        overrides = [f"dynamics={dynamics}", "swarm=grid", "swarm.n=64", "environment=open"]
        runs.append((" ".join(overrides), overrides))
    runs.append(("observers=[swarmlab]", ["scenario=flocking", "observers=[swarmlab]"]))  # its compiled pass
    return runs


def main(argv: list[str] | None = None) -> int:
    """``swarmscene-compile``: run the warm-up scenarios, so numba's kernels are compiled and cached."""
    parser = argparse.ArgumentParser(prog="swarmscene-compile", description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    from ..composition.compose import compose
    from ..runs.build import build, shortened

    runs = warmups()
    failed = 0
    start = time.perf_counter()
    for i, (label, overrides) in enumerate(runs, 1):
        began = time.perf_counter()
        try:
            build(shortened(compose(overrides))).run()
            word = "ok"
        except Exception as exc:  # one line per failed warm-up; the others still compile
            failed += 1
            word = f"FAILED: {' '.join(str(exc).split())[:200]}"
        print(f"swarmscene-compile: [{i}/{len(runs)}] {label}: {time.perf_counter() - began:.1f} s {word}",
              file=sys.stderr, flush=True)
    print(f"swarmscene-compile: {len(runs) - failed} of {len(runs)} warm-up runs in "
          f"{time.perf_counter() - start:.1f} s; numba's cache is filled", file=sys.stderr)
    return 1 if failed else 0


def entry() -> None:
    """Console script ``swarmscene-compile``."""
    sys.exit(main())


if __name__ == "__main__":
    entry()
