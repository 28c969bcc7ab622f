"""Every shipped preset's metrics and trajectory, fingerprinted, to show a change keeps the numbers.

    python benchmarks/preset_fingerprint.py --write benchmarks/results/fingerprint.json   # before
    python benchmarks/preset_fingerprint.py --check benchmarks/results/fingerprint.json   # after

``--check`` prints, per preset, whether the trajectory is bit-identical and the largest relative
difference of any metric (wall-clock metrics left out), and exits 1 when a metric moved by more
than ``--rtol`` (1e-9) or a key appeared or vanished. ``--only NAME`` limits the presets.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WALL_CLOCK = {"wall_time", "realtime_factor", "step_ms_median", "cem.step_ms_median", "vrb.planning_ms"}


def presets() -> list[str]:
    """The names of the shipped presets (``scenarios/scenario/*.yaml``), sorted."""
    return sorted(p.stem for p in (ROOT / "scenarios" / "scenario").glob("*.yaml"))


def fingerprint(name: str) -> dict:
    """One preset's metrics (wall-clock ones left out) and the SHA-256 of its whole trajectory."""
    from swarmscene import api

    result = api.run([f"scenario={name}"])
    digest = hashlib.sha256()
    for key in sorted(result.trajectory):
        digest.update(key.encode())
        digest.update(result.trajectory[key].tobytes())
    metrics = {k: v for k, v in result.metrics.items() if k not in WALL_CLOCK}
    return {"metrics": json.loads(json.dumps(metrics, default=str)), "trajectory": digest.hexdigest()}


def _rel(a, b) -> float:
    if isinstance(a, bool) or isinstance(b, bool) or not isinstance(a, (int, float)) or not isinstance(b, (int, float)):
        return 0.0 if a == b else math.inf
    if a is None or b is None:
        return 0.0 if a == b else math.inf
    if math.isnan(a) and math.isnan(b):
        return 0.0
    if a == b:
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def compare(old: dict, new: dict, rtol: float) -> tuple[bool, str]:
    """Whether ``new`` keeps ``old``'s metric keys and values within ``rtol``, and a line saying how they differ."""
    keys = set(old["metrics"]) | set(new["metrics"])
    missing = sorted(k for k in keys if (k in old["metrics"]) != (k in new["metrics"]))
    worst, worst_key = 0.0, ""
    for key in keys - set(missing):
        r = _rel(old["metrics"][key], new["metrics"][key])
        if r > worst:
            worst, worst_key = r, key
    same_traj = old["trajectory"] == new["trajectory"]
    ok = not missing and worst <= rtol
    text = f"trajectory {'bit-identical' if same_traj else 'DIFFERS'}; max rel metric diff {worst:.3g}"
    if worst_key:
        text += f" ({worst_key}: {old['metrics'][worst_key]!r} -> {new['metrics'][worst_key]!r})"
    if missing:
        text += f"; keys added/removed: {missing}"
    return ok, text


def main() -> int:
    """Write every preset's fingerprint (``--write``) or check them against a file (``--check``); the exit status."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", type=Path, help="write the fingerprint of every preset to this file")
    mode.add_argument("--check", type=Path, help="compare every preset with this fingerprint file")
    parser.add_argument("--only", action="append", help="a preset name (repeatable)")
    parser.add_argument("--rtol", type=float, default=1e-9)
    args = parser.parse_args()
    names = args.only or presets()
    if args.write:
        out = {name: fingerprint(name) for name in names}
        args.write.parent.mkdir(parents=True, exist_ok=True)
        args.write.write_text(json.dumps(out, indent=1, sort_keys=True))
        print(f"wrote {len(out)} presets to {args.write}")
        return 0
    old = json.loads(args.check.read_text())
    failed = 0
    for name in names:
        if name not in old:
            print(f"{name}: not in {args.check}")
            failed += 1
            continue
        ok, text = compare(old[name], fingerprint(name), args.rtol)
        failed += not ok
        print(f"{'ok  ' if ok else 'DIFF'} {name}: {text}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
