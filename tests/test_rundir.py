"""swarmscene.runs.rundir: every file of a run directory checked (size, type, links, aliases, the
trajectory's headers and shapes), each problem one RunFileError line naming the file."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from swarmscene import api
from swarmscene.runs import rundir
from swarmscene.runs.rundir import RunDir, RunFileError


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("rundir") / "run"
    api.run(["clock.duration=0.5", "output.summary=false"], output_dir=path)
    return path


@pytest.fixture
def copy(run, tmp_path) -> Path:
    import shutil

    target = tmp_path / "run"
    shutil.copytree(run, target)
    return target


def problem(call) -> str:
    with pytest.raises(RunFileError) as info:
        call()
    text = str(info.value)
    assert "\n" not in text
    return text


def test_a_complete_run_reads_back(run):
    d = RunDir(run)
    assert d.manifest()["complete"] is True and d.metrics()["steps"] == 5
    assert d.config()["clock"]["duration"] == 0.5 and not d.has(".hydra/overrides.yaml")  # api.run: no Hydra
    traj = d.trajectory()
    assert traj["pos"].shape == (6, 5, 3) and traj["healthy"].dtype == bool and list(traj["t"]) == pytest.approx(
        [0, 0.1, 0.2, 0.3, 0.4, 0.5])
    d.check_trajectory()
    assert d.has("metrics.json") and not d.has("error.json")


def test_the_recorded_config_reads_back_as_the_scenarios_data(tmp_path):
    """config.yaml (written by libyaml's emitter where PyYAML has it) reads back to the scenario's
    data, a description with escapes, quotes, non-ASCII text and a wrapped long line included."""
    from swarmscene.runs.outputs import CONFIG_HEADER

    description = ("Corridor \u00e9t\u00e9 \u2192 '#1': \"tab\"\there, a colon: and a line\nbreak, \u4e2d "
                   * 6).strip()
    data = api.compose(["clock.duration=0.2", "output.summary=false"])
    api.run({**data, "description": description}, output_dir=tmp_path / "run")
    text = (tmp_path / "run" / "config.yaml").read_text()
    assert text.startswith(CONFIG_HEADER)
    recorded = RunDir(tmp_path / "run").config()
    assert recorded["description"] == description
    assert recorded == json.loads(json.dumps(api.load({**data, "description": description}).data))


def test_a_missing_directory_or_a_file_in_its_place(tmp_path):
    assert problem(lambda: RunDir(tmp_path / "nope")) == f"{tmp_path}/nope: not a run directory (missing, or not a directory)"
    (tmp_path / "file").write_text("x")
    assert problem(lambda: RunDir(tmp_path / "file")).endswith("not a run directory (missing, or not a directory)")


@pytest.mark.parametrize("content, words", [
    ("[1, 2]", "should hold a mapping, holds list"),
    ('"a string"', "should hold a mapping, holds str"),
    ("null", "should hold a mapping, holds null"),
    ('{"a": 1', "not valid JSON (Expecting ',' delimiter"),
    ('{"a": NaN}', "not valid JSON (non-standard number NaN)"),
    ('{"a": Infinity}', "not valid JSON (non-standard number Infinity)"),
    ("", "not valid JSON (Expecting value"),
    ("[" * 100000, "not valid JSON"),
])
def test_damaged_json_names_the_file(copy, content, words):
    (copy / "metrics.json").write_text(content)
    assert problem(RunDir(copy).metrics).startswith(f"{copy}/metrics.json: {words}")


def test_non_utf8_missing_links_and_directories(copy, tmp_path):
    (copy / "manifest.json").write_bytes(b'{"a": "\xff"}')
    assert problem(RunDir(copy).manifest) == f"{copy}/manifest.json: not UTF-8 text"
    (copy / "metrics.json").unlink()
    assert problem(RunDir(copy).metrics) == f"{copy}/metrics.json: missing"
    secret = tmp_path / "secret.json"
    secret.write_text('{"token": 1}')
    (copy / "metrics.json").symlink_to(secret)
    assert problem(RunDir(copy).metrics).endswith("is a symbolic link (refused: a run directory's files are plain files)")
    (copy / "error.json").mkdir()
    assert problem(RunDir(copy).error) == f"{copy}/error.json: not a regular file"


def test_sizes_are_limited_before_reading(copy, monkeypatch):
    monkeypatch.setattr(rundir, "MAX_JSON_BYTES", 10)
    assert problem(RunDir(copy).metrics).startswith(f"{copy}/metrics.json: too large (")
    monkeypatch.setattr(rundir, "MAX_YAML_BYTES", 10)
    assert problem(RunDir(copy).config).endswith("; at most 10)")


@pytest.mark.parametrize("content, words", [
    ("a: &x [1, 2]\nb: *x\n", "holds YAML aliases (refused: the engine never writes them)"),
    ("a: [1, 2\n", "not valid YAML (while parsing a flow sequence"),
    ("- 1\n- 2\n", "should hold a mapping, holds list"),
    ("a: !!python/object:os.system {}\n", "not valid YAML (could not determine a constructor"),
])
def test_damaged_yaml_names_the_file(copy, content, words):
    (copy / "config.yaml").write_text(content)
    assert problem(RunDir(copy).config).startswith(f"{copy}/config.yaml: {words}")


def test_overrides_must_be_a_list(copy):
    (copy / ".hydra").mkdir(exist_ok=True)
    (copy / ".hydra" / "overrides.yaml").write_text("a: 1\n")
    assert problem(RunDir(copy).overrides) == f"{copy}/.hydra/overrides.yaml: should hold a list, holds dict"


def _npz(path: Path, **arrays) -> None:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    path.write_bytes(buffer.getvalue())


def _good(steps: int = 4, n: int = 2) -> dict[str, np.ndarray]:
    return {"t": np.arange(steps) * 0.1, "pos": np.zeros((steps, n, 3)), "vel": np.zeros((steps, n, 3)),
            "healthy": np.ones((steps, n), bool)}


def test_a_truncated_or_garbage_trajectory(copy):
    path = copy / "trajectory.npz"
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    assert problem(RunDir(copy).trajectory).startswith(f"{path}: not a readable numpy archive (")
    path.write_bytes(b"garbage")
    assert problem(RunDir(copy).check_trajectory) == f"{path}: not a readable numpy archive (File is not a zip file)"
    path.unlink()
    assert problem(RunDir(copy).trajectory) == f"{path}: missing (was the run made with output.trajectory=false?)"


def test_trajectory_arrays_are_checked_by_name_shape_and_dtype(copy):
    path = copy / "trajectory.npz"
    arrays = _good()
    del arrays["vel"]
    _npz(path, **arrays)
    assert problem(RunDir(copy).trajectory) == f"{path}: lacks the array(s) vel"
    _npz(path, **{**_good(), "healthy": np.ones((4, 3), bool)})
    assert problem(RunDir(copy).trajectory) == f"{path}: array 'healthy' has shape (4, 3), expected (4, 2)"
    _npz(path, **{**_good(), "pos": np.zeros((4, 2))})
    assert problem(RunDir(copy).trajectory) == f"{path}: array 'pos' has shape (4, 2), expected 3 axes"
    _npz(path, **{**_good(), "quat": np.zeros((4, 2, 3))})
    assert problem(RunDir(copy).trajectory) == f"{path}: array 'quat' has shape (4, 2, 3), expected (4, 2, 4)"
    _npz(path, **{**_good(), "t": np.array([0.0, 0.2, 0.1, 0.3])})
    assert problem(RunDir(copy).trajectory) == f"{path}: array 't' is not finite and increasing"


def test_arrays_of_text_records_or_complex_numbers_and_empty_ones_are_refused(copy, monkeypatch):
    """Only object arrays were refused: 't' as text failed in every reader with a TypeError, a
    record dtype with numpy's promotion error, complex positions were cast to real in silence, an
    empty trajectory failed with an IndexError; a header promising more than the machine's memory
    (a bomb of zeros: 6 MB on disk, 9.3 GB loaded) was read."""
    path = copy / "trajectory.npz"
    cases = [({"t": np.array(["0", "1", "2", "3"])}, "array 't' holds <U1 values, not real numbers"),
             ({"pos": np.zeros((4, 2, 3), dtype=[("a", "f8")])}, "array 'pos' holds [('a', '<f8')] values, not real numbers"),
             ({"vel": np.zeros((4, 2, 3), complex)}, "array 'vel' holds complex128 values, not real numbers"),
             ({"healthy": np.full((4, 2), 0.5)}, "array 'healthy' holds float64 values, not flags")]
    for change, line in cases:
        _npz(path, **{**_good(), **change})
        assert problem(RunDir(copy).trajectory) == f"{path}: {line}"
    _npz(path, **_good(steps=0))
    assert problem(RunDir(copy).trajectory) == f"{path}: array 'pos' holds no frame (shape (0, 2, 3))"
    _npz(path, **_good(n=0))
    assert problem(RunDir(copy).trajectory) == f"{path}: array 'pos' holds no agent (shape (4, 0, 3))"
    _npz(path, **_good())
    monkeypatch.setattr(rundir, "_physical_memory", lambda: 100)  # a machine of 100 bytes
    assert problem(RunDir(copy).trajectory).startswith(f"{path}: its arrays would take 0.0 GiB in memory, more than")


def test_a_run_directory_that_is_a_link_is_refused(run, tmp_path):
    """The tools that write into a run directory (the replay, the pictures) wrote through a link."""
    (tmp_path / "link").symlink_to(run, target_is_directory=True)
    assert problem(lambda: RunDir(tmp_path / "link")) == (
        f"{tmp_path / 'link'}: is a symbolic link (refused: a run directory is a plain directory)")


def test_the_config_values_the_views_read_are_checked(copy):
    """An event without its time, a seed or a range that is not a number failed deep inside the
    replay (KeyError, ValueError) instead of one line naming config.yaml."""
    import yaml

    from swarmscene.views.plots import load_run

    config = yaml.safe_load((copy / "config.yaml").read_text())
    cases = [("events", [{"name": "fail", "agents": [0]}], "events.0.at should be a number of seconds, holds None"),
             ("seed", "abc", "seed should be a number, holds 'abc'"),
             ("comm", {**(config.get("comm") or {}), "range": "far"}, "comm.range should be a number, holds 'far'")]
    for key, value, line in cases:
        (copy / "config.yaml").write_text(yaml.safe_dump({**config, key: value}))
        assert problem(lambda: load_run(copy)) == f"{copy / 'config.yaml'}: {line}"


def test_a_pickled_array_is_refused_without_unpickling(copy):
    path = copy / "trajectory.npz"
    arrays = _good()
    arrays["pos"] = np.empty((4, 2, 3), dtype=object)
    with zipfile.ZipFile(path, "w") as zf:
        for name, array in arrays.items():
            with zf.open(f"{name}.npy", "w") as member:
                np.lib.format.write_array(member, array, allow_pickle=True)
    assert problem(RunDir(copy).check_trajectory) == \
        f"{path}: array 'pos' holds Python objects (refused: nothing is unpickled)"


def test_finite_or_none():
    assert rundir.finite_or_none(1) == 1.0 and rundir.finite_or_none(2.5) == 2.5
    for value in (None, True, "1", float("nan"), float("inf"), [1]):
        assert rundir.finite_or_none(value) is None


def test_read_text_checks_like_the_others(copy):
    assert rundir.read_text(copy / "config.yaml").startswith("# The effective configuration")
    (copy / "config.yaml").write_bytes(b"\xff\xfe")
    assert problem(lambda: rundir.read_text(copy / "config.yaml")) == f"{copy}/config.yaml: not UTF-8 text"
    assert json.loads(rundir.read_text(copy / "metrics.json"))["steps"] == 5
