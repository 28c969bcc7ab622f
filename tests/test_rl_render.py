"""render_mode="human": a matplotlib window where a display exists, a one-line refusal where none does.

The window path runs pyplot's own machinery (figure managers, ``show``, the canvas's event loop)
through a test backend: the Agg canvas, with a figure manager that records what it was asked to
show and an event loop that records how long it was asked to run instead of waiting."""

from __future__ import annotations

import importlib
import sys

import numpy as np
import pytest

pytest.importorskip("matplotlib")
import matplotlib.pyplot as plt  # noqa: E402

from swarmscene.env import SwarmGymEnv, SwarmParallelEnv, make_env, make_gym_env, render_frame  # noqa: E402

SWAP = ["scenario=swap", "swarm.n=4"]
NO_WINDOW = r"render_mode: 'human' needs a window, and {}; render_mode='rgb_array' returns the frames instead"

BACKEND = '''
from matplotlib.backend_bases import FigureManagerBase
from matplotlib.backends.backend_agg import FigureCanvasAgg

shown = []   # the figures the window manager was asked to show
loops = []   # how long the GUI event loop was asked to run, per frame


class FigureManager(FigureManagerBase):
    def show(self):
        shown.append(self.canvas.figure)


class FigureCanvas(FigureCanvasAgg):
    manager_class = FigureManager

    def start_event_loop(self, timeout=0):
        loops.append(timeout)
'''


@pytest.fixture
def window(tmp_path, monkeypatch):
    """A display and an interactive backend (the test one); the previous backend afterwards."""
    (tmp_path / "swarmscene_test_window.py").write_text(BACKEND)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("DISPLAY", ":0")
    previous = plt.get_backend()
    plt.switch_backend("module://swarmscene_test_window")
    yield importlib.import_module("swarmscene_test_window")
    plt.close("all")
    plt.switch_backend(previous)
    sys.modules.pop("swarmscene_test_window", None)


def shown_frame(env) -> np.ndarray:
    return np.asarray(env.renderer.window.image.get_array())


def test_both_environments_list_human_among_their_render_modes():
    assert SwarmGymEnv.metadata["render_modes"] == ["rgb_array", "human"]
    assert SwarmParallelEnv.metadata["render_modes"] == ["rgb_array", "human"]


@pytest.mark.parametrize("make", [make_env, make_gym_env])
def test_human_is_refused_in_one_line_without_a_display(make, monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    message = NO_WINDOW.format(r"there is no display \(neither DISPLAY nor WAYLAND_DISPLAY is set\)")
    with pytest.raises(ValueError, match=f"^{message}$"):
        make(SWAP, render_mode="human")


def test_human_is_refused_in_one_line_with_a_non_interactive_backend(monkeypatch):
    monkeypatch.setenv("DISPLAY", ":0")
    previous = plt.get_backend()
    plt.switch_backend("agg")
    try:
        with pytest.raises(ValueError, match=f"^{NO_WINDOW.format('matplotlib.s backend .agg. is not interactive')}$"):
            make_gym_env(SWAP, render_mode="human")
    finally:
        plt.switch_backend(previous)


def test_a_wayland_display_is_a_display(window, monkeypatch):
    monkeypatch.delenv("DISPLAY")
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-0")
    monkeypatch.setattr(sys, "platform", "linux")
    assert make_gym_env(SWAP, render_mode="human").render_mode == "human"


def test_the_gym_window_shows_each_frame_as_rgb_array_draws_it(window):
    env = make_gym_env(SWAP, render_mode="human")
    assert plt.get_fignums() == []  # nothing opens before the first reset
    env.reset(seed=0)
    assert len(plt.get_fignums()) == 1 and window.shown == [env.renderer.window.figure]
    first = shown_frame(env)
    np.testing.assert_array_equal(first, render_frame(env.driver, "rgb_array"))
    assert env.render() is None  # human mode shows, it returns nothing

    env.step(np.ones(env.action_space.shape, dtype=np.float32))
    second = shown_frame(env)
    np.testing.assert_array_equal(second, render_frame(env.driver, "rgb_array"))
    assert not np.array_equal(first, second)  # the agents moved, the time changed
    assert len(plt.get_fignums()) == 1 and len(window.shown) == 1  # updated in place, not a new window

    # one event-loop run per frame (reset, render, step), each for what is left of the 0.1 s period
    assert len(window.loops) == 3 and window.loops[0] == pytest.approx(0.1)
    assert all(1e-3 <= t <= 0.1 for t in window.loops)
    env.close()
    assert plt.get_fignums() == []


def test_a_closed_window_reopens_at_the_next_frame(window):
    env = make_gym_env(SWAP, render_mode="human")
    env.reset(seed=0)
    plt.close("all")  # the user closes the window
    env.step(np.zeros(env.action_space.shape, dtype=np.float32))
    assert len(plt.get_fignums()) == 1 and len(window.shown) == 2
    np.testing.assert_array_equal(shown_frame(env), render_frame(env.driver, "rgb_array"))


def test_the_parallel_window_follows_reset_and_step(window):
    env = make_env(SWAP, render_mode="human")
    env.reset(seed=1)
    env.step({a: np.ones(3, dtype=np.float32) for a in env.agents})
    np.testing.assert_array_equal(shown_frame(env), render_frame(env.driver, "rgb_array"))
    assert len(window.loops) == 2 and len(plt.get_fignums()) == 1
    env.close()
    assert plt.get_fignums() == []
