"""Generate docs/gallery.md: one picture per shipped preset, drawn by swarmscene itself.

    python docs/make_gallery.py            # runs every preset (~1 min), writes docs/gallery/*.png and docs/gallery.md
    python docs/make_gallery.py --only swap

Each preset is run as a user would run it (``swarmscene scenario=NAME output.plots=true``, through
``swarmscene.api``); its ``trajectories.png`` is copied into docs/gallery/ and the page shows it
with the preset's description, the command and the run's headline numbers. Needs the plots extra
(matplotlib). ``tests/test_gallery.py`` fails when a preset has no picture on the page.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GALLERY = ROOT / "docs" / "gallery"
PAGE = ROOT / "docs" / "gallery.md"

HEADER = """# Gallery

One picture per shipped preset (`scenarios/scenario/`), drawn by the tool itself: each is the
`trajectories.png` that `output.plots=true` writes into the run directory (top-down paths, the
obstacles, where each agent started and ended, failed vehicles marked). Regenerate the page and
its pictures with `python docs/make_gallery.py` (plots extra). The numbers under each picture are
that run's own metrics (docs/outputs.md); the full verdict lines are what `swarmscene` prints.
"""


def presets() -> list[str]:
    return sorted(p.stem for p in (ROOT / "scenarios" / "scenario").glob("*.yaml"))


def _fmt(value, unit: str = "") -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.3g}{unit}"
    return f"{value}{unit}"


def render(name: str, workdir: Path) -> str:
    """Run one preset with plots, copy its picture, return its section of the page."""
    from swarmscene import api

    run_dir = workdir / name
    result = api.run([f"scenario={name}", "output.plots=true", "output.summary=false"], output_dir=run_dir)
    GALLERY.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(run_dir / "trajectories.png", GALLERY / f"{name}.png")
    config = api.load([f"scenario={name}"]).config
    m = result.metrics
    methods = f"{config.formation.name} / {config.avoidance.name} / {config.dynamics.name}"
    return "\n".join([
        f"## {name}",
        "",
        f"{config.description}. Methods: {methods}.",
        "",
        f"![{name}: trajectories](gallery/{name}.png)",
        "",
        f"`swarmscene scenario={name}`: {m['agents']} agents, {_fmt(m['duration'], ' s')} simulated "
        f"({m['stop_reason']}); min separation {_fmt(m.get('min_separation'), ' m')}, min clearance "
        f"{_fmt(m.get('min_clearance'), ' m')}, success {m.get('success')}.",
        "",
    ])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", action="append", help="a preset name (repeatable); the page keeps the others")
    args = parser.parse_args()
    names = presets()
    todo = args.only or names
    unknown = sorted(set(todo) - set(names))
    if unknown:
        print(f"make_gallery: unknown preset(s) {unknown} (valid: {', '.join(names)})", file=sys.stderr)
        return 2
    sections = _existing_sections()
    with tempfile.TemporaryDirectory() as tmp:
        for name in todo:
            print(f"gallery: {name}", file=sys.stderr)
            sections[name] = render(name, Path(tmp))
    PAGE.write_text(HEADER + "\n" + "\n".join(sections[n] for n in names if n in sections))
    print(f"wrote {PAGE} ({len(sections)} presets)")
    return 0


def _existing_sections() -> dict[str, str]:
    """The page's current section of each preset, so ``--only`` redraws one and keeps the rest."""
    if not PAGE.is_file():
        return {}
    sections: dict[str, str] = {}
    for block in PAGE.read_text().split("\n## ")[1:]:
        name = block.split("\n", 1)[0].strip()
        sections[name] = "## " + block.rstrip("\n") + "\n"
    return sections


if __name__ == "__main__":
    sys.exit(main())
