"""Renamed metric keys (docs/outputs.md, "Renamed keys"): the page lists exactly the plugins' renames,
and a run's metrics.json keeps every old key beside its new one, with the same value, this release."""

from __future__ import annotations

import json
import re
from pathlib import Path

from swarmscene import api
from swarmscene.plugins.avoidance.cem import CEM

OUTPUTS = Path(__file__).resolve().parents[1] / "docs" / "outputs.md"


def test_outputs_page_lists_every_rename():
    rows = re.findall(r"^\| `([\w.]+)` \| `([\w.]+)` \|", OUTPUTS.read_text(), re.M)
    assert dict(rows) == CEM.RENAMED_METRICS


def test_metrics_json_keeps_old_and_new_keys_with_the_same_value(tmp_path):
    api.run(["scenario=cem_six_vehicle", "clock.duration=3", "output.summary=false"], output_dir=tmp_path)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    for old, new in CEM.RENAMED_METRICS.items():
        assert isinstance(metrics[new], bool) and metrics[old] == metrics[new]
