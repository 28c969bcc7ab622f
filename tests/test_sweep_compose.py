"""A job composed by the sweeps' caching loader equals Hydra's own composition of it.

The workers (and the Ray launcher's main process) compose each distinct set of config-group
overrides once and apply a job's plain values to a copy (swarmscene.sweeps.compose): here both
compositions are compared, ``hydra`` node included, for every preset and a sample of grids, and a
bad value gives Hydra's own error.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

from swarmscene.sweeps import compose

PRESETS = sorted(p.stem for p in (Path(compose.__file__).parents[2] / "scenarios" / "scenario").glob("*.yaml"))

GRIDS = [
    # (group overrides, value overrides of three jobs)
    ([], [["seed=0"], ["seed=7"], ["++clock.duration=3.5", "seed=2"]]),
    (["avoidance=cem"], [["++avoidance.K=2"], ["++avoidance.K=5", "seed=1"]]),
    (["+sweep=fast"], [["++formation.speed=1.0", "seed=0"], ["++formation.speed=2.0", "seed=1"]]),
    (["scenario=cem_six_vehicle"], [["++events.0.at=21.3", "seed=3"], ["++output.progress=off", "seed=4"]]),
    (["scenario=indoor_corridor"], [["++environment.width=0.7", "seed=5"], ["~output.objective"]]),
    (["disturbances=[dryden,gps]"], [["seed=9"]]),
]


@pytest.fixture(scope="module")
def hydra_loader():
    from hydra import initialize_config_module
    from hydra.core.global_hydra import GlobalHydra
    from hydra.types import RunMode

    from swarmscene.composition.searchpath import register_search_path

    register_search_path()
    with initialize_config_module(config_module="swarmscene.scenarios", version_base="1.3"):
        loader = GlobalHydra.instance().config_loader()
        master = loader.load_configuration("config", ["hydra.sweep.dir=multirun/x"], RunMode.MULTIRUN)
        yield loader, master


def _both(hydra_loader, overrides):
    from omegaconf import OmegaConf

    loader, master = hydra_loader
    # A pickled copy, as a launcher hands it to a worker: its cache is the process's.
    caching = pickle.loads(pickle.dumps(compose.GroupCachingLoader(loader)))
    ours = caching.load_sweep_config(master, list(overrides))
    theirs = loader.load_sweep_config(master, list(overrides))
    return OmegaConf.to_container(ours, resolve=False), OmegaConf.to_container(theirs, resolve=False), ours


@pytest.mark.parametrize("preset", PRESETS)
def test_every_preset_composes_as_hydra_composes_it(hydra_loader, preset):
    for values in ([], ["seed=3"], ["++clock.duration=2.0", "seed=11"]):  # ([]: the grid check's call)
        ours, theirs, cfg = _both(hydra_loader, [f"scenario={preset}", *values])
        assert ours == theirs
        assert list(cfg.hydra.overrides.task) == [f"scenario={preset}", *values]


@pytest.mark.parametrize("groups,jobs", GRIDS)
def test_a_sample_of_grids_composes_as_hydra_composes_it(hydra_loader, groups, jobs):
    compose._COMPOSED.clear()
    for values in jobs:
        for order in (groups + values, values + groups):  # the overrides' order is kept too
            ours, theirs, _ = _both(hydra_loader, order)
            assert ours == theirs, order
    # One composition for the grid's one set of group overrides, wherever the values stand.
    assert len(compose._COMPOSED) == 1


def test_flags_and_resolution_match_hydras(hydra_loader):
    from omegaconf import OmegaConf

    _, _, cfg = _both(hydra_loader, ["scenario=swap", "seed=5"])
    loader, master = hydra_loader
    theirs = loader.load_sweep_config(master, ["scenario=swap", "seed=5"])
    assert OmegaConf.is_struct(cfg) == OmegaConf.is_struct(theirs) is True
    from omegaconf.errors import ConfigAttributeError

    with pytest.raises(ConfigAttributeError):
        cfg.not_a_key = 1  # struct: a new key is refused as in Hydra's
    task = {k: v for k, v in OmegaConf.to_container(cfg, resolve=False).items() if k != "hydra"}
    assert task["seed"] == 5


def test_a_bad_value_gives_hydras_own_error(hydra_loader):
    from hydra.errors import ConfigCompositionException

    loader, master = hydra_loader
    caching = compose.GroupCachingLoader(loader)
    for bad in (["avoidance.K=2"], ["+seed=3"], ["~no.such.key"]):  # a plain change of a missing key
        with pytest.raises(ConfigCompositionException) as ours:
            caching.load_sweep_config(master, ["avoidance=cem", *bad])
        with pytest.raises(ConfigCompositionException) as theirs:
            loader.load_sweep_config(master, ["avoidance=cem", *bad])
        assert str(ours.value) == str(theirs.value)


def test_the_command_reaches_the_job_through_env_set(hydra_loader):
    import json

    from swarmscene.runs.outputs import COMMAND_ENV

    loader, master = hydra_loader
    typed = ["swarmscene", "-m", "seed=1,2", "avoidance.K=2"]
    caching = compose.GroupCachingLoader(loader, command=typed)
    for job in (["seed=1"], ["avoidance=cem"]):  # a value, and group overrides alone
        cfg = caching.load_sweep_config(master, job)
        assert json.loads(cfg.hydra.job.env_set[COMMAND_ENV]) == typed


def test_compositions_handed_to_a_worker_spare_it_composing(hydra_loader, monkeypatch):
    """The grid's check composes a sweep's group overrides in the main process; a pool's worker
    adopts those compositions (pickled, as the pool's initializer hands them) and composes none of
    them again, by either path a job takes (a job's config, a launcher task's lean job), and its
    job's config is Hydra's all the same."""
    from hydra._internal.config_loader_impl import ConfigLoaderImpl
    from omegaconf import OmegaConf

    loader, master = hydra_loader
    compose._COMPOSED.clear()
    compose.GroupCachingLoader(loader).load_sweep_config(master, ["scenario=swap"])  # the check's call
    handed = pickle.loads(pickle.dumps(compose.compositions()))
    assert len(handed) == 1
    compose._COMPOSED.clear()  # a worker's own cache, empty at its start
    compose.adopt(handed)
    worker, task_worker = (pickle.loads(pickle.dumps(compose.GroupCachingLoader(loader, command=command)))
                           for command in (None, ["swarmscene", "-m", "seed=4,5"]))
    monkeypatch.setattr(ConfigLoaderImpl, "load_sweep_config", lambda *a, **k: pytest.fail("composed again"))
    job = worker.load_sweep_config(master, ["scenario=swap", "seed=4"])
    task, _ = task_worker.load_task_job(master, ["scenario=swap", "seed=5"])
    monkeypatch.undo()
    theirs = loader.load_sweep_config(master, ["scenario=swap", "seed=4"])
    assert OmegaConf.to_container(job, resolve=False) == OmegaConf.to_container(theirs, resolve=False)
    assert OmegaConf.to_container(task, resolve=False)["seed"] == 5
