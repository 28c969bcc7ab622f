"""The built wheel contains every package and YAML file that the editable install sees."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAPPING = {
    "swarmscene": "swarmscene", "core": "swarmscene/core", "plugins": "swarmscene/plugins",
    "scenarios": "swarmscene/scenarios", "methods": "swarmscene/methods",
    "hydra_plugins": "hydra_plugins",
}


def source_files() -> set[str]:
    """Every .py, .yaml and plugin README in the mapped source folders, as wheel paths."""
    found = set()
    for folder, target in MAPPING.items():
        for path in (ROOT / folder).rglob("*"):
            if "__pycache__" in path.parts or not path.is_file():
                continue
            if path.suffix in (".py", ".yaml") or (path.name == "README.md" and folder in ("plugins", "methods")):
                found.add(f"{target}/{path.relative_to(ROOT / folder).as_posix()}")
    return found


def test_wheel_contains_every_package_and_yaml(tmp_path):
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp_path), str(ROOT)],
        check=True,
        capture_output=True,
    )
    (wheel,) = tmp_path.glob("swarmscene-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = sorted(source_files() - names)
    assert not missing, f"in the source tree but not in the wheel: {missing}"
    assert any(n.endswith("entry_points.txt") and "console_scripts" in zipfile.ZipFile(wheel).read(n).decode() for n in names)
