"""Boids side by side: swarmscene's ``scenario=flocking`` against a numpy + cKDTree reference and Mesa.

    python benchmarks/speed/peers/bench_boids.py            # the cases below, 3 alternations
    python benchmarks/speed/peers/bench_boids.py --quick    # fewer steps, one pass

Every side starts from the same state (positions uniform in the torus, heading components uniform
in [-1, 1], Mesa's own draws, seed 0) and runs the flocking preset's parameters, read from the
composed and validated preset (vision 10 m, separation 2 m, weights 0.03 / 0.015 / 0.05, 1 m per
1 s step, kinematic points with u_max 2 m/s, comm.range 20 m, separation limit 0.3 m), in a torus
of side L = 10 sqrt(N) m: the preset's density, 100 boids per 100 m x 100 m, as its own comment
scales it (``formation.box_max``); one more row at N = 1,000 keeps Mesa's default 100 m box (ten
times denser: more neighbours per boid).

- swarmscene: ``scenario=flocking swarm.n=N formation.box_max=[L,L,L]`` with the explicit start,
  ``output.trajectory=false``, through ``swarmscene.api`` (the whole engine tick: the safety monitor
  measures separation and connectivity every tick); ticks timed by the engine (``step_seconds``);
- numpy: ``boids_numpy.py`` (same rules, same parameters, same monitor work per step, plain numpy
  and scipy, no swarmscene) in the same interpreter;
- Mesa: ``mesa.examples.basic.boid_flockers`` (``bench_mesa.py``'s child, its own venv), boids
  moved one at a time in random order; N = 1,000 only (its cost grows as N^2).

Each run is a fresh process pinned to one core with one thread; the sides alternate ``--repeat``
times and each side's fastest run counts. Steps/s are over the steps after the first ``WARM``.
The final polarization |mean unit heading| of swarmscene and the reference must agree (same rule,
same start: they differ by the order of floating-point sums at most); the runner prints both.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
from pathlib import Path

import numpy as np
import peerlib
from bench_mesa import MESA_CHILD, mesa_python
from peerlib import HERE, alternate, child_json

WARM = 3
"""ticks left out of the rate (first calls, caches)"""

SWARMSCENE_CHILD = r"""
import json, sys, warnings
import numpy as np
from swarmscene import api
start = np.load(sys.argv[1]); steps = int(sys.argv[2]); box = float(sys.argv[3])
n = len(start["pos"])
data = api.compose(["scenario=flocking", f"swarm.n={n}", f"clock.duration={steps}",
                    f"formation.box_max=[{box!r},{box!r},{box!r}]", "output.trajectory=false",
                    "output.summary=false"])
data["swarm"]["start"] = {"layout": "explicit", "positions": np.column_stack(
    [start["pos"], np.full(n, 2.0)]).tolist()}
data["safety"]["start_overlap"] = "warn"  # a uniform random start puts some boids close
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    sim = api.build(data)
sim.formation.heading = np.column_stack([start["dir"], np.zeros(n)])
result = sim.run()
m = result.metrics
assert m["steps"] == steps, m
print(json.dumps({"step_seconds": sim.step_seconds.tolist(), "polarization": m["flocking.polarization"],
                  "min_separation": m["min_separation"], "collisions": m["collisions"],
                  "connected": m["connected"], "mean_neighbours": m["flocking.mean_neighbours"]}))
"""

PARAMS_CHILD = r"""
import json
from swarmscene import api
s = api.load(["scenario=flocking"])
f, c = s.plugin_params["formation"], s.config
print(json.dumps({"vision": f.vision, "separation": f.separation, "cohere": f.cohere,
                  "separate": f.separate, "match": f.match, "speed": f.speed,
                  "dt": c.clock.guidance_period, "u_max": s.plugin_params["dynamics"].u_max,
                  "comm_range": c.comm.range, "separation_limit": c.safety.separation_limit,
                  "space": f.space, "planar": f.planar, "dynamics": c.dynamics.name}))
"""


def preset_params() -> dict:
    """The flocking preset's values, from the composed and validated scenario."""
    params = child_json([peerlib.swarmscene_python(), "-c", PARAMS_CHILD])
    assert params.pop("space") == "toroidal" and params.pop("planar") is True, params
    assert params.pop("dynamics") == "single_integrator", params
    return params


def cases(quick: bool) -> list[dict]:
    """(N, box side, steps, with Mesa) per row."""
    dense = dict(n=1000, box=100.0, steps=20 if quick else 100, mesa_steps=8 if quick else 25,
                 note="Mesa's default 100 m box")
    return [
        dict(n=1000, box=10 * math.sqrt(1000), steps=20 if quick else 100, mesa_steps=8 if quick else 25,
             note="preset density"),
        dict(n=10000, box=10 * math.sqrt(10000), steps=10 if quick else 60, mesa_steps=0,
             note="preset density"),
        dense,
    ]


def initial_state(n: int, box: float, seed: int = 0) -> dict[str, np.ndarray]:
    """Mesa's draws: positions uniform in the box, heading components uniform in [-1, 1]."""
    rng = np.random.default_rng(seed)
    return {"pos": rng.random((n, 2)) * box, "dir": rng.uniform(-1.0, 1.0, size=(n, 2))}


def rate(run: dict, warm: int = WARM) -> float:
    """Steps per second over the steps after the first ``warm``."""
    seconds = run["step_seconds"][warm:]
    return len(seconds) / sum(seconds)


def compare(quick: bool = False, repeat: int = 3, log=print) -> dict:
    """Every case, the sides alternating ``repeat`` times; each side's fastest run kept."""
    params = preset_params()
    mesa = mesa_python()
    python = peerlib.swarmscene_python()
    reference = str(HERE / "boids_numpy.py")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for case in cases(quick):
            n, box, steps = case["n"], case["box"], case["steps"]
            start = Path(tmp) / f"start_{n}_{box:g}.npz"
            np.savez(start, **initial_state(n, box))
            ref_params = {**params, "box": box}
            mesa_params = dict(width=box, height=box, speed=params["speed"] * params["dt"],
                               vision=params["vision"], separation=params["separation"],
                               cohere=params["cohere"], separate=params["separate"], match=params["match"])
            sides = {
                "swarmscene": [python, "-c", SWARMSCENE_CHILD, str(start), str(steps), repr(box)],
                "numpy": [python, reference, str(start), str(steps), json.dumps(ref_params)],
            }
            if case["mesa_steps"]:
                sides["mesa"] = [str(mesa), "-c", MESA_CHILD, str(start), str(case["mesa_steps"]),
                                 json.dumps(mesa_params)]
            best = alternate({side: (cmd, None) for side, cmd in sides.items()}, repeat, "steps_per_s",
                             measure=lambda result: {**result, "steps_per_s": rate(result)})
            row = {"n": n, "box_m": box, "steps": steps, "mesa_steps": case["mesa_steps"], "note": case["note"]}
            for side, result in best.items():
                row[side] = {k: v for k, v in result.items() if k != "step_seconds"}
            ok = {side for side, result in best.items() if "error" not in result}
            if {"swarmscene", "numpy"} <= ok:
                row["ratio_numpy"] = best["swarmscene"]["steps_per_s"] / best["numpy"]["steps_per_s"]
                row["polarization_gap"] = abs(best["swarmscene"]["polarization"] - best["numpy"]["polarization"])
            if {"swarmscene", "mesa"} <= ok:
                row["ratio_mesa"] = best["swarmscene"]["steps_per_s"] / best["mesa"]["steps_per_s"]
            log(f"  boids N = {n:,}, L = {box:.0f} m, {steps} steps: " + "; ".join(
                f"{side} {r['steps_per_s']:.3g} steps/s, polarization {r['polarization']:.6f}"
                if "error" not in r else f"{side} FAILED: {r['error']}" for side, r in best.items()))
            rows.append(row)
    return {"params": params, "warm_steps": WARM, "repeat": repeat, "rows": rows,
            "mesa_version": next((r["mesa"]["version"] for r in rows if "mesa" in r), None)}


def main() -> None:
    """Print the comparison with the numpy reference and Mesa (:func:`compare`) as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print(json.dumps(compare(args.quick, 1 if args.quick else args.repeat), indent=1))


if __name__ == "__main__":
    main()
