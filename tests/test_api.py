"""The Python API for notebooks: api.run honours every output option or refuses it in one line,
and api.sweep runs a grid with a launcher and returns the tidy table, with the command line's
resume and failure records."""

from __future__ import annotations

import json

import pytest

from swarmscene import api
from swarmscene.core.errors import ConfigError

SHORT = ["clock.duration=1.0", "output.summary=false"]


def test_run_writes_the_optional_outputs_into_its_directory(tmp_path):
    result = api.run([*SHORT, "output.plots=true"], output_dir=tmp_path / "run")
    assert result.run_dir == tmp_path / "run"
    files = json.loads((tmp_path / "run" / "manifest.json").read_text())["files"]
    assert {"trajectories.png", "safety.png", "speed.png", "altitude.png"} <= set(files)


@pytest.mark.parametrize("option", ["plots", "animation", "rerun"])
def test_run_without_a_directory_refuses_file_outputs_in_one_line(option):
    with pytest.raises(ConfigError) as err:
        api.run([*SHORT, f"output.{option}=true"])
    assert err.value.lines == [
        f"output.{option}=true: writes files, so it needs a run directory: api.run(..., output_dir=...)"
    ]


def test_run_prints_the_summary_when_asked_and_is_quiet_otherwise(capsys):
    api.run(SHORT)
    assert capsys.readouterr().out == ""
    api.run(["clock.duration=1.0"])  # output.summary defaults to true, as on the command line
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "swarmscene: scenario 'default' (static_shape / potential / double_integrator)"
    assert out[1].startswith("  simulated 1 s in 10 steps, 5 agents, stopped by duration")


def test_sweep_returns_the_table_and_resumes(tmp_path):
    first = api.sweep({"seed": [0, 1]}, SHORT, sweep_dir=tmp_path / "sw")
    assert first.exit_status == 0 and [row["status"] for row in first.rows] == ["complete", "complete"]
    table = first.table()
    assert type(table).__name__ == "DataFrame" and list(table["seed"]) == [0, 1]
    assert set(table["min_separation"]) and (table["steps"] == 10).all()
    started = [json.loads((tmp_path / "sw" / str(i) / "manifest.json").read_text())["started_at"] for i in (0, 1)]
    again = api.sweep({"seed": [0, 1]}, SHORT, sweep_dir=tmp_path / "sw")  # the same grid: resumed
    assert [row["config_hash"] for row in again.rows] == [row["config_hash"] for row in first.rows]
    # complete jobs were skipped, not run again: their manifests are the first sweep's
    assert [json.loads((tmp_path / "sw" / str(i) / "manifest.json").read_text())["started_at"] for i in (0, 1)] == started


def test_sweep_refuses_a_bad_grid_before_any_job_and_records_failed_jobs(tmp_path):
    with pytest.raises(ConfigError) as err:
        api.sweep({"avoidance.K": [1, 0]}, [*SHORT, "avoidance=cem"], sweep_dir=tmp_path / "bad")
    assert err.value.lines == ["job 1 (avoidance.K=0): avoidance.K: must be >= 1 (got 0)"]
    assert not (tmp_path / "bad" / "0").exists()
    result = api.sweep({"swarm.leader": [0, 7]}, [*SHORT, "hydra/sweeper=swarmscene", "hydra.sweeper.on_invalid=record"],
                       launcher="joblib", sweep_dir=tmp_path / "rec")
    assert [row["status"] for row in result.rows] == ["complete", "failed"]
    assert result.failed[0]["reason"] == "invalid"
    with pytest.raises(ConfigError, match="1 of 2 jobs failed"):
        api.sweep({"swarm.leader": [0, 7]}, [*SHORT, "hydra/sweeper=swarmscene", "hydra.sweeper.on_invalid=record"],
                  sweep_dir=tmp_path / "strict", allow_failed=False)


def test_sweep_names_an_unknown_launcher_in_one_line():
    with pytest.raises(ConfigError) as err:
        api.sweep({"seed": [0]}, launcher="slurm")
    assert err.value.lines == ["launcher: must be one of basic, pool, batch, joblib, ray, submitit_slurm (got 'slurm')"]


@pytest.mark.parametrize(("overrides", "line"), [
    (["formation=nope"], "formation: unknown option 'nope' (valid: "),
    (["swarm.n=[1"], "swarm.n: cannot parse override: "),
    (["name=${nope}"], "name: cannot resolve the value: Interpolation key 'nope' not found"),
    (["nokey=1"], "nokey: unknown key (got '1')"),
])
def test_a_composition_error_is_one_line_as_on_the_command_line(overrides, line):
    """api.run raised Hydra's multi-line exception (the options list, the search path) where
    api.sweep and the command line give one line."""
    from swarmscene.core.errors import ConfigError

    with pytest.raises(ConfigError) as err:
        api.run(overrides)
    assert len(err.value.lines) == 1 and err.value.lines[0].startswith(line), err.value.lines
    assert "\n" not in str(err.value)


def test_an_events_choice_replaces_a_presets_events():
    """cem_six_vehicle's failure is its defaults list's events choice (events/cem_six_vehicle.yaml),
    so `events=none` on the command line replaces it; it used to be the preset's own key, which
    came after the groups and silently won (then a refusal)."""
    assert api.compose(["scenario=cem_six_vehicle"])["events"] == [{"at": 2.0, "agents": [0], "name": "hover"}]
    assert api.compose(["scenario=cem_six_vehicle", "events=none"])["events"] == []
    assert api.compose(["scenario=cem_six_vehicle", "events=lead_fails"])["events"][0]["at"] == 10.0
    assert api.compose(["scenario=cem_six_vehicle", "events.0.at=5"])["events"][0]["at"] == 5
    assert api.compose(["scenario=default", "events=lead_fails"])["events"][0]["at"] == 10.0
