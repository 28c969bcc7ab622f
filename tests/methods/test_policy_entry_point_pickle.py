"""A policy from the deprecated entry-point group ``swarmscene.policies`` pickles (issue #27): its
class is a module attribute of ``methods.policy.policies``, the same class each time the group is
listed, so a launcher (joblib, Ray) can pickle a scenario that names it, and a worker process that
never listed the group finds it by name."""

from __future__ import annotations

import pickle
import subprocess
import sys
import textwrap
from importlib import metadata

import numpy as np
import pytest

from swarmscene import api
from swarmscene.methods.policy import policies

ALONE = ["swarm.n=1", "swarm.leader=null", "environment=open", "dynamics=single_integrator",
         "formation=static_shape", "clock.duration=2"]
POLICY = ["avoidance=policy", "avoidance.policy=climb.up", "avoidance.policy_options.rate=0.25",
          "avoidance.max_speed=4"]
FACTORY = """\
import numpy as np


class Climb:  # a module-level callable, so a built policy pickles too
    def __init__(self, rate):
        self.rate = rate

    def __call__(self, obs):
        return np.tile([0.0, 0.0, self.rate], (len(obs), 1))


def make(layout, spec, rate=0.5):
    return Climb(rate)
"""


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """A distribution on sys.path whose entry point ``climb.up`` (a dot: pickle splits names at
    dots) is listed in the group swarmscene.policies, found by importlib.metadata as any installed one."""
    (tmp_path / "climb_policy.py").write_text(FACTORY)
    info = tmp_path / "climb_policy-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: climb-policy\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[swarmscene.policies]\nclimb.up = climb_policy:make\n")
    monkeypatch.delitem(sys.modules, "climb_policy", raising=False)  # another test's module of that name
    monkeypatch.syspath_prepend(str(tmp_path))
    # A lister of its own: the group's listing is cached per lister, and this one sees tmp_path.
    monkeypatch.setattr(policies, "entry_points", lambda group: metadata.entry_points(group=group))
    return tmp_path


def _scenario():
    with pytest.warns(DeprecationWarning, match="swarmscene_register_policies"):
        return api.load([*ALONE, *POLICY], api.plugins()[1])


def _climb(run):
    return run.trajectory["pos"][:, 0, 2] - run.trajectory["pos"][0, 0, 2]


def test_the_class_is_a_module_attribute_and_the_same_for_every_listing(installed):
    first = _scenario().plugin_params["avoidance"].policy_class
    second = _scenario().plugin_params["avoidance"].policy_class
    assert first is second and first.name == "climb.up"
    assert getattr(policies, first.__qualname__) is first
    assert pickle.loads(pickle.dumps(first)) is first
    with pytest.raises(AttributeError, match="has no attribute 'FactoryPolicy\\[nope\\]'"):
        policies.__getattr__("FactoryPolicy[nope]")


def test_a_scenario_naming_it_and_a_built_policy_pickle(installed):
    scenario = _scenario()
    again = pickle.loads(pickle.dumps(scenario))
    assert again.plugin_params["avoidance"].policy_class is scenario.plugin_params["avoidance"].policy_class
    with pytest.warns(DeprecationWarning):  # the run's own plugin manager lists the group again
        run = api.run(again)
    np.testing.assert_allclose(_climb(run), np.arange(21) * 0.1, atol=1e-12)  # 1 m/s for 2 s
    cls = scenario.plugin_params["avoidance"].policy_class
    built = cls(cls.Params.model_validate({"rate": 0.25}), None, None)
    assert pickle.loads(pickle.dumps(built))(np.zeros((2, 5))).tolist() == [[0.0, 0.0, 0.25]] * 2


def test_a_worker_process_that_never_listed_the_group_loads_the_scenario(installed):
    (installed / "scenario.pickle").write_bytes(pickle.dumps(_scenario()))
    worker = textwrap.dedent("""\
        import pickle, sys, warnings
        from swarmscene import api
        from swarmscene.methods.policy import policies
        assert not policies._FACTORY_POLICIES
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # found by name (no plugin manager, no deprecation warning)
            scenario = pickle.loads(open(sys.argv[1], "rb").read())
        assert scenario.plugin_params["avoidance"].policy_class.name == "climb.up"
        warnings.simplefilter("ignore", DeprecationWarning)  # the run lists the group: it warns
        z = api.run(scenario).trajectory["pos"][:, 0, 2]
        print(round(float(z[-1] - z[0]), 9))
    """)
    done = subprocess.run([sys.executable, "-c", worker, str(installed / "scenario.pickle")], cwd=installed,
                          capture_output=True, text=True, timeout=120,
                          env={"PYTHONPATH": str(installed), "PATH": "/usr/bin:/bin"})
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[-1] == "2.0"
