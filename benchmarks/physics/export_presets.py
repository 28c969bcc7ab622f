"""Every shipped preset through the Crazyflie export into the README's lab box (issue #37).

    python benchmarks/physics/export_presets.py [--box XMIN YMIN ZMIN XMAX YMAX ZMAX] [--only NAME]

Runs each preset (its default duration), exports the flown or planned show with ``--fit-box`` and
prints one row per preset: the exit status, the scale applied and the export's first line of
refusal (or "written" and the safety margins). Nothing is written for a refused show; a written one
goes to a temporary folder. The table in docs/physics.md is this script's output.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def presets() -> list[str]:
    """Every shipped preset's name."""
    return sorted(p.stem for p in (ROOT / "scenarios" / "scenario").glob("*.yaml"))


def export_row(name: str, box: list[str], work: Path) -> str:
    """Run preset ``name``, export it fitted into ``box``, and return its table row (exit, first line)."""
    from swarmscene import api
    from swarmscene.views import export

    run_dir = work / name
    sim = api.build([f"scenario={name}", "output.summary=false"])
    api.write_outputs(sim, sim.run(), run_dir)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            export.main([str(run_dir), "--crazyflie", str(work / f"{name}_cf"), "--fit-box", *box, "--force"])
            code = 0
        except SystemExit as exc:
            code = int(exc.code or 0)
    lines = [line for line in err.getvalue().splitlines() if "warning: " not in line or "refused" in line]
    placed = next((line.strip() for line in out.getvalue().splitlines() if line.strip().startswith("placed:")), "")
    what = lines[-1].split(": ", 1)[1] if lines else placed
    return f"| {name} | {code} | {what} |"


def main() -> int:
    """Print the export's verdict on every preset fitted into the box, as a Markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--box", nargs=6, default=["-2", "-2", "0", "2", "2", "2"])
    parser.add_argument("--only", action="append")
    args = parser.parse_args()
    print("| preset | exit | export (first refusal, or the placement and margins) |")
    print("|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.only or presets():
            print(export_row(name, args.box, Path(tmp)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
