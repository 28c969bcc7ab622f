"""docs/gallery.md shows every shipped preset with its picture (python docs/make_gallery.py)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_preset_has_a_picture_on_the_gallery_page():
    presets = sorted(p.stem for p in (ROOT / "scenarios" / "scenario").glob("*.yaml"))
    page = (ROOT / "docs" / "gallery.md").read_text()
    sections = re.findall(r"^## (\S+)$", page, flags=re.M)
    assert sections == presets  # one section per preset, in name order; none left over
    for name in presets:
        picture = ROOT / "docs" / "gallery" / f"{name}.png"
        assert f"](gallery/{name}.png)" in page
        assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_readme_links_the_gallery():
    assert "(docs/gallery.md)" in (ROOT / "README.md").read_text()
