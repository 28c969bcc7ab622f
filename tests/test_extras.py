"""The optional extras resolve together in any order: every extra that names a package names it
with the same version range, and the test extra (which installs them all at once) carries the
same ranges, so installing them one at a time cannot leave a range another extra excludes."""

from __future__ import annotations

import tomllib
from pathlib import Path

from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[1]


def extras() -> dict[str, list[Requirement]]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    return {name: [Requirement(r) for r in reqs] for name, reqs in project["optional-dependencies"].items()}


def test_a_package_named_by_several_extras_has_one_range():
    ranges: dict[str, dict[str, str]] = {}
    for extra, reqs in extras().items():
        for req in reqs:
            ranges.setdefault(req.name.lower(), {})[extra] = str(req.specifier)
    differing = {name: by for name, by in ranges.items() if len(set(by.values())) > 1}
    assert not differing, f"one range per package across extras: {differing}"


def test_the_cloudpickle_conflict_is_pinned_away():
    """joblib 1.6 requires cloudpickle >= 3 and hydra-ray-launcher 1.2 cloudpickle < 3: the joblib
    extra (and the test extra) keep joblib below 1.6."""
    by_extra = extras()
    for extra in ("joblib", "test"):
        joblib = next(r for r in by_extra[extra] if r.name == "joblib")
        assert "1.6.0" not in joblib.specifier and "1.5.3" in joblib.specifier


def test_the_train_extra_carries_the_rl_extra_and_the_test_extra_carries_train():
    """pip install '.[train]' alone gives the environments and the libraries of docs/rl.md's
    training recipes; the tests run them, so the test extra names the same packages."""
    by_extra = {extra: {r.name.lower(): str(r.specifier) for r in reqs} for extra, reqs in extras().items()}
    train, test = by_extra["train"], by_extra["test"]
    assert by_extra["rl"].items() <= train.items()
    assert {"stable-baselines3", "supersuit"} <= set(train)
    assert train.items() <= test.items()


def test_torch_is_pinned_to_the_cpu_wheel_in_the_test_extra_only():
    """Any torch spec but the CPU wheel the CI image carries pulls a multi-GB CUDA build there; a
    user's train extra takes whatever torch Stable-Baselines3 accepts."""
    by_extra = extras()
    torch = [r for r in by_extra["test"] if r.name == "torch"]
    assert [str(r.specifier) for r in torch] == ["==2.13.0"]
    assert not any(r.name == "torch" for extra, reqs in by_extra.items() if extra != "test" for r in reqs)
