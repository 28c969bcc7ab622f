"""The command line: default run, composition flags, one-line errors with exit status 2."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

EXE = [sys.executable, "-c", "from swarmscene.cli import main; main()"]


def swarmscene(*args: str, cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    full_env = {**os.environ, **(env or {})}
    full_env.pop("HYDRA_FULL_ERROR", None)
    return subprocess.run([*EXE, *args], cwd=cwd, capture_output=True, text=True, env=full_env, timeout=120)


def test_default_scenario_writes_run_directory(tmp_path):
    proc = swarmscene(f"hydra.run.dir={tmp_path}/run", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    for needle in ("simulated", "agents", "min separation", "min clearance", "real-time factor", "outputs:",
                   "success True (no engine limit violated, mission complete)\n", "\n  OK      separation: min ", "\n  OK      mission: complete at "):
        assert needle in out
    run = tmp_path / "run"
    assert {p.name for p in run.iterdir()} >= {"config.yaml", "metrics.json", "trajectory.npz", "manifest.json"}
    metrics = json.loads((run / "metrics.json").read_text())
    for key in ("min_separation", "min_clearance", "collisions", "connected", "success", "duration", "realtime_factor", "step_ms_median"):
        assert key in metrics
    assert metrics["success"] is True and metrics["collisions"] == 0
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["complete"] is True and manifest["seed"] == 0 and len(manifest["config_hash"]) == 64
    assert manifest["versions"]["numpy"]
    import numpy as np

    traj = np.load(run / "trajectory.npz")
    assert traj["pos"].shape[1:] == (5, 3) and traj["t"][0] == 0.0


@pytest.mark.parametrize(
    ("args", "line"),
    [
        (["formation=nope"], "swarmscene: formation: unknown option 'nope' (valid: "),
        (["bogus=1"], "swarmscene: bogus: unknown key (got '1')"),
        (["avoidance.K=0"], "swarmscene: avoidance.K: unknown key (valid keys: v_max, influence, obstacle_influence, lookahead) (got 0)"),
        (["=3"], "swarmscene: =3: an override needs a key before '=' (key=value; got '=3')"),
        (["+swarm.n=3"], "swarmscene: Could not append to config. An item is already at 'swarm.n'. Either remove + prefix: 'swarm.n=3' Or add a second + to add or override 'swarm.n': '++swarm.n=3'"),
        (["scenario=cem_six_vehicle", "avoidance.K=0"], "swarmscene: avoidance.K: must be >= 1 (got 0)"),
        (["swarm.n=0"], "swarmscene: swarm.n: must be >= 1 (got 0)"),
        (["clock.guidance_period=-1"], "swarmscene: clock.guidance_period: must be > 0.0 (got -1)"),
        (["clock.physics_step=0.03"], "swarmscene: clock.physics_step: must divide clock.guidance_period = 0.1 (got 0.03)"),
        (["events=lead_fails", "events.0.agents=[9]"], "swarmscene: events.0.agents: agents are 0..4 (got [9])"),
        (["formation.waypoints=[]"], "swarmscene: formation.waypoints: must have at least 1 item(s) (got [])"),
        (["swarm.n=abc"], "swarmscene: swarm.n: must be an integer (got 'abc')"),
        (["swarm.n=[1"], "swarmscene: swarm.n: cannot parse override"),
        (["swarm.n=true"], "swarmscene: swarm.n: must be a number, not true/false (got True)"),
        (["events.1.agents=[9]"], "swarmscene: events.1.agents: cannot set this key: list index out of range (got '[9]')"),
        (["name=${nope}"], "swarmscene: name: cannot resolve the value: Interpolation key 'nope' not found"),
        (["clock.duration=1e12"], "swarmscene: clock.duration: must be <= 1000000000.0 (got 1000000000000.0)"),
        (["clock.duration=1e8"], "swarmscene: clock.duration: at most 10000000 guidance ticks of "
                                 "clock.guidance_period = 0.1 s (got 100000000.0: 1e+09 ticks)"),
        (["swarm.start.layout=random", "swarm.n=100000"], "swarmscene: swarm.start: cannot place 100000 agents 2.0 m "
                                                         "apart in a 10.0 m square (at most 39 fit; raise swarm.start.extent)"),
        (["swarm.n=100000"], "swarmscene: formation: 'static_shape' cannot be built for this scenario "
                             "(swarm.n = 100000): MemoryError: Unable to allocate"),
        (["formation=reynolds_flocking", "formation.space=toroidal", "formation.vision=60"],
         "swarmscene: formation.vision: must be below half the torus' smallest side 100.0 (got 60.0)"),
    ],
)
def test_bad_input_one_line_exit_2_nothing_left_behind(tmp_path, args, line):
    proc = swarmscene(*args, f"hydra.run.dir={tmp_path}/run", cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(line), lines[0]
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "run").exists()


def test_debug_env_shows_traceback(tmp_path):
    proc = swarmscene("swarm.n=0", f"hydra.run.dir={tmp_path}/run", cwd=tmp_path, env={"SWARMSCENE_DEBUG": "1"})
    assert proc.returncode != 0 and "Traceback" in proc.stderr


def test_help_lists_every_group_and_option(tmp_path):
    proc = swarmscene("--help", cwd=tmp_path)
    assert proc.returncode == 0
    for group in ("swarm", "environment", "formation", "avoidance", "dynamics", "events", "scenario"):
        assert f"{group}:" in proc.stdout
    for option in ("static_shape", "potential", "cem", "double_integrator", "single_integrator", "cem_six_vehicle"):
        assert option in proc.stdout


def test_cfg_job_and_info(tmp_path):
    proc = swarmscene("--cfg", "job", "avoidance=none", cwd=tmp_path)
    assert proc.returncode == 0 and "avoidance:\n  name: none" in proc.stdout
    proc = swarmscene("--info", "searchpath", cwd=tmp_path)
    assert proc.returncode == 0 and "pkg://swarmscene.scenarios" in proc.stdout


def test_shell_completion(tmp_path):
    proc = swarmscene("-sc", "query=bash", cwd=tmp_path, env={"COMP_LINE": "swarmscene avoidance="})
    assert proc.returncode == 0
    assert {"avoidance=none", "avoidance=potential", "avoidance=cem"} <= set(proc.stdout.split())
    proc = swarmscene("-sc", "install=bash", cwd=tmp_path)
    assert proc.returncode == 0 and "complete -o nospace -o default -F hydra_bash_completion" in proc.stdout


def test_every_documented_option_is_set_with_plain_key_value(tmp_path):
    """Options absent from the composed YAML (plugin defaults, swarm.start.extent) need no `+`."""
    proc = swarmscene("--cfg", "job", "dynamics.k_v=3.5", "swarm.start.extent=9", "swarm.start.connected=true",
                      "avoidance=cem", "avoidance.K=5", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for text in ("k_v: 3.5", "extent: 9", "connected: true", "K: 5"):
        assert text in proc.stdout


def test_multirun_sweeps_a_plain_option_absent_from_the_yaml(tmp_path):
    proc = swarmscene("--multirun", "scenario=cem_six_vehicle", "avoidance.K=1,2", "clock.duration=1",
                      "output.trajectory=false", f"hydra.sweep.dir={tmp_path}/m", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    import yaml

    ks = [yaml.safe_load((tmp_path / "m" / job / "config.yaml").read_text())["avoidance"]["K"] for job in ("0", "1")]
    assert ks == [1, 2]


def test_plain_command_line_rewrites_only_dotted_value_overrides():
    from swarmscene.composition.searchpath import plain_command_line

    argv = ["--multirun", "-cn", "config", "--cfg", "job", "avoidance=cem", "avoidance.K=1,2", "+a.b=1",
            "++c.d=2", "~e.f", "seed=3", "hydra.run.dir=x", "hydra/launcher=joblib", "g.h@pkg=1", "i.j=[1"]
    assert plain_command_line(argv) == [
        "--multirun", "-cn", "config", "--cfg", "job", "avoidance=cem", "++avoidance.K=1,2", "+a.b=1",
        "++c.d=2", "~e.f", "seed=3", "hydra.run.dir=x", "hydra/launcher=joblib", "g.h@pkg=1", "i.j=[1"]
    assert plain_command_line(["-sc", "query=bash", "a.b=1"]) == ["-sc", "query=bash", "a.b=1"]


def test_a_yaml_file_that_does_not_parse_is_one_line_with_file_and_line(tmp_path):
    conf = tmp_path / "conf" / "avoidance"
    conf.mkdir(parents=True)
    (conf / "broken.yaml").write_text("name: potential\nv_max: [1.0\n")
    proc = swarmscene("--config-dir", str(tmp_path / "conf"), "avoidance=broken", f"hydra.run.dir={tmp_path}/run",
                      cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"swarmscene: {conf / 'broken.yaml'}:3:1: cannot parse YAML: expected ',' or ']', but got '<stream end>' "
        "(while parsing a flow sequence started at line 2)"]
    assert not (tmp_path / "run").exists()


NON_FINITE_RUN = """
import numpy as np
from swarmscene import cli
from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator

step = DoubleIntegrator.step

def overflowing_step(self, world, dt):
    step(self, world, dt)
    if world.t >= 0.5:
        world.pos[3, 0] = np.inf
        world.vel[3] = np.array([1e308]) * 10.0  # numpy warns "overflow encountered"

DoubleIntegrator.step = overflowing_step
cli.main()
"""
"""The command line with a double integrator that turns non-finite 0.5 s into the run."""


def test_a_non_finite_state_ends_the_run_as_failed_in_one_line(tmp_path):
    """The kernel stops at the first non-finite state; the command prints that one line, keeps the
    outputs up to then, marks the run failed (error.json, manifest status) and exits with 1.

    Run as a user runs it, in a process of its own: the test process's warnings filters (a test
    module's library may set DeprecationWarnings to "always" at collection) are not a user's."""
    from swarmscene import cli

    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTHONWARNINGS")}
    proc = subprocess.run([sys.executable, "-c", NON_FINITE_RUN, "clock.duration=2", f"hydra.run.dir={tmp_path}/run"],
                          cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == cli.EXIT_FAILED, proc.stderr
    # One line, and no summary: a run that did not fly gets no "OK separation" verdict, and numpy's
    # overflow warning on the way there is not repeated.
    assert proc.stdout == "", proc.stdout
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith("swarmscene: non-finite state of agent 3 at tick 6 (t = 0.6 s; 1 agents)")
    assert err[0].endswith(f"outputs up to then (marked failed) in {tmp_path / 'run'}")
    manifest = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert manifest["status"] == "failed" and manifest["error"].startswith("RunFailed: non-finite state of agent 3")
    assert json.loads((tmp_path / "run" / "error.json").read_text())["reason"] == "non-finite"
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["stop_reason"] == "non_finite" and metrics["success"] is False and metrics["steps"] == 5


DIVIDING_RUN = """
from swarmscene import cli
from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator

step = DoubleIntegrator.step

def dividing_step(self, world, dt):
    step(self, world, dt)
    if world.t >= 0.5:
        world.pos[0, 0] = 1 / 0

dividing_step.__code__ = dividing_step.__code__.replace(co_name="step")  # as the plugin names it
DoubleIntegrator.step = dividing_step
cli.main()
"""
"""The command line with a double integrator that divides by zero 0.5 s into the run."""


def test_an_exception_in_a_plugin_names_it_exits_1_and_keeps_the_run(tmp_path):
    """A plugin's exception 0.5 s into a run: one line naming the kind, the plugin, the method and
    the time; exit 1 (the run started and failed, not bad input); the outputs up to then written,
    marked failed, with the plugin's traceback in error.json. Run in a process of its own, as a
    user runs it (see the non-finite test)."""
    import numpy as np

    from swarmscene import cli

    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTHONWARNINGS")}
    script = tmp_path / "dividing_run.py"  # a file, so the traceback quotes the plugin's line
    script.write_text(DIVIDING_RUN)
    proc = subprocess.run([sys.executable, str(script), "clock.duration=2", f"hydra.run.dir={tmp_path}/run"],
                          cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == cli.EXIT_FAILED == 1, proc.stderr
    assert proc.stdout == ""
    assert proc.stderr.splitlines() == [
        "swarmscene: dynamics 'double_integrator' raised in step at t = 0.5 s: ZeroDivisionError: division by zero; "
        f"outputs up to then (marked failed) in {tmp_path / 'run'}"]
    run = tmp_path / "run"
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["complete"] is False and manifest["status"] == "failed"
    error = json.loads((run / "error.json").read_text())
    assert error["reason"] == "plugin-error" and "world.pos[0, 0] = 1 / 0" in error["traceback"]
    metrics = json.loads((run / "metrics.json").read_text())
    assert metrics["stop_reason"] == "plugin_error" and metrics["success"] is False and metrics["steps"] == 5
    assert np.load(run / "trajectory.npz")["t"][-1] == pytest.approx(0.5)


def test_an_observer_hook_that_raises_is_named_with_its_hook(tmp_path):
    """An observer's ``swarmscene_step_end`` raising: named as the observer and the hook."""
    from swarmscene import api
    from swarmscene.core.raised import PluginRaised
    from swarmscene.plugin import hookimpl

    class Faulty:
        def __init__(self, sim):
            pass

        @hookimpl
        def swarmscene_step_end(self, sim):
            if sim.t >= 0.3:
                raise KeyError("agent")

    pm, registry = api.plugins()
    registry.observers.append(Faulty)
    sim = api.build(["clock.duration=1"], (pm, registry))
    with pytest.raises(PluginRaised) as raised:
        sim.run()
    assert str(raised.value) == "observer 'Faulty' raised in swarmscene_step_end at t = 0.3 s: KeyError: 'agent'"
    assert isinstance(raised.value.__cause__, KeyError)
    assert raised.value.result.metrics["steps"] == 3 and raised.value.result.stop_reason == "plugin_error"


def test_a_deprecation_reaches_a_command_line_user_once(tmp_path):
    """A hook reading a deprecated name every tick (swarmscene.plugin.EventKind): the warning is shown, once."""
    plugin = tmp_path / "reader.py"
    plugin.write_text(
        "from swarmscene import plugin\n"
        "from swarmscene.plugin import hookimpl\n"
        "class Reader:\n"
        "    def __init__(self, sim):\n        pass\n"
        "    @hookimpl\n"
        "    def swarmscene_step_end(self, sim):\n        plugin.EventKind\n"
        "@hookimpl\n"
        "def swarmscene_register_observers(register):\n    register(Reader)\n")
    code = (f"import sys; sys.path.insert(0, {str(tmp_path)!r})\n"
            "from swarmscene.core import registry\n"
            "from swarmscene import builtins\n"
            "builtins.BUILTIN_PLUGINS = (*builtins.BUILTIN_PLUGINS, 'reader')\n"
            "from swarmscene import api\n"
            "api.BUILTIN_PLUGINS = builtins.BUILTIN_PLUGINS\n"
            "from swarmscene.cli import main; main()\n")
    env = {**os.environ}
    env.pop("HYDRA_FULL_ERROR", None)
    env.pop("PYTHONWARNINGS", None)
    proc = subprocess.run([sys.executable, "-c", code, "clock.duration=1", f"hydra.run.dir={tmp_path}/run"],
                          cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("SwarmsceneDeprecationWarning: swarmscene.plugin.EventKind is deprecated") == 1, proc.stderr


def test_a_sweep_preset_chosen_without_a_plus_gets_the_plus_hint(tmp_path):
    proc = swarmscene("sweep=fast", cwd=tmp_path)
    assert proc.returncode == 2
    assert proc.stderr.strip() == "swarmscene: sweep: not in the defaults list: add it with a plus, +sweep=fast (got sweep=fast)"
    assert not any(tmp_path.iterdir())


def test_output_piped_into_a_reader_that_leaves_is_not_an_error_line(tmp_path):
    """`swarmscene --help | head -1`: the reader closes the pipe; the command stops quietly with
    141 (128 + SIGPIPE, as shells report it) instead of printing a BrokenPipeError line."""
    proc = subprocess.Popen([*EXE, "--help"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    proc.stdout.close()  # the reader is gone before the help is written (start-up takes far longer)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 141 and err == ""


def test_a_division_by_zero_names_the_options_set_to_zero(monkeypatch):
    """A numeric option that makes a plugin divide by zero: the line names the option, not only
    the plugin, at run time and when the plugin is built."""
    from swarmscene import api
    from swarmscene.core.errors import ConfigError
    from swarmscene.core.raised import PluginRaised
    from swarmscene.plugins.dynamics.double_integrator import DoubleIntegrator

    control, init = DoubleIntegrator.control, DoubleIntegrator.__init__

    def control_dividing(self, world, setpoints):
        control(self, world, setpoints)
        return 1.0 / self.params.K_Wv

    control_dividing.__code__ = control_dividing.__code__.replace(co_name="control")
    monkeypatch.setattr(DoubleIntegrator, "control", control_dividing)
    with pytest.raises(PluginRaised) as raised:
        api.build(["dynamics.K_Wv=0", "clock.duration=0.3"]).run()
    assert str(raised.value) == ("dynamics 'double_integrator' raised in control (with dynamics.K_Wv = 0) "
                                 "at t = 0 s: ZeroDivisionError: float division by zero")

    def init_dividing(self, params, ctx):
        init(self, params, ctx)
        1.0 / params.K_Wv

    import types

    plugin_module = sys.modules[DoubleIntegrator.__module__].__dict__  # raised from the plugin's own module
    init_dividing = types.FunctionType(init_dividing.__code__, plugin_module, "__init__", None,
                                       init_dividing.__closure__)
    monkeypatch.setattr(DoubleIntegrator, "__init__", init_dividing)
    with pytest.raises(ConfigError) as err:
        api.build(["dynamics.K_Wv=0"])
    assert err.value.lines == ["dynamics: 'double_integrator' cannot be built for this scenario (swarm.n = 5) "
                               "(with dynamics.K_Wv = 0): ZeroDivisionError: float division by zero"]


def test_a_recorded_config_run_again_writes_under_the_scenarios_name(tmp_path):
    """`--config-path <run dir> --config-name config` (and the falsifier's worst_case.yaml): the
    recorded file has no hydra node, and Hydra's default wrote to outputs/<date>/<time>."""
    first = swarmscene("scenario=cem_two_vehicle", "clock.duration=0.3", "output.summary=false",
                       f"hydra.run.dir={tmp_path}/first", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    work = tmp_path / "work"
    work.mkdir()
    again = swarmscene("--config-path", str(tmp_path / "first"), "--config-name", "config", cwd=work)
    assert again.returncode == 0, again.stderr
    runs = list((work / "outputs").iterdir())
    assert [p.name for p in runs] == ["cem_two_vehicle"] and len(list(runs[0].iterdir())) == 1
    chosen = swarmscene("--config-path", str(tmp_path / "first"), "--config-name", "config",
                        f"hydra.run.dir={tmp_path}/mine", cwd=work)
    assert chosen.returncode == 0 and (tmp_path / "mine" / "metrics.json").is_file()  # the user's own wins
