"""Re-record tests/data/preset_compositions.json: each shipped preset's validated effective config
with its default methods (the engine's schema dump and each chosen plugin's Params dump).

Run it only when a preset's values are meant to change (a new preset, a deliberate new default),
and say so in the commit: tests/test_composition.py holds every preset to these values.

    python tests/data/record_preset_compositions.py            # every preset
    python tests/data/record_preset_compositions.py swap       # one preset (added or changed)
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from test_composition import PRESETS, REGISTRY, effective  # noqa: E402

from swarmscene import api  # noqa: E402


def main(names: list[str]) -> None:
    path = HERE / "preset_compositions.json"
    recorded = json.loads(path.read_text()) if names and path.exists() else {}
    for name in names or PRESETS:
        recorded[name] = effective(api.load([f"scenario={name}"], REGISTRY))
    path.write_text(json.dumps(recorded, indent=1, sort_keys=True) + "\n")
    print(f"{path}: {', '.join(recorded)}")


if __name__ == "__main__":
    main(sys.argv[1:])
