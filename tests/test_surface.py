"""What a user meets first: objects that plot themselves, figures that show in notebooks,
honest rendering, editor-visible signatures, portable run configs, the typed marker."""

from __future__ import annotations

import inspect
import re
import warnings
from pathlib import Path

import gymnasium as gym
import matplotlib
import numpy as np
import pytest
from matplotlib.axes import Axes

import fricenv
from fricenv import plotting

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def trajectory() -> fricenv.Trajectory:
    return fricenv.simulate(fricenv.OscillatorParams(nu=0.1, u0=1.15), 60.0)


@pytest.fixture(scope="module")
def rmap() -> fricenv.RegimeMap:
    return fricenv.regime_map("coulomb", np.geomspace(0.5, 20.0, 3), [0.1, 1.0, 2.5],
                              progress=False)


def test_trajectory_plot_returns_axes(trajectory):
    import matplotlib.pyplot as plt

    ax = trajectory.plot()
    assert isinstance(ax, Axes)
    line = ax.get_lines()[0]
    np.testing.assert_array_equal(line.get_ydata(), trajectory.v)
    assert ax.collections, "stick intervals are shaded"
    _, ax2 = plt.subplots()
    assert trajectory.plot(ax2, y="x") is ax2
    np.testing.assert_array_equal(ax2.get_lines()[0].get_ydata(), trajectory.x)
    with pytest.raises(ValueError, match="y must be 'v' or 'x', got 'z'"):
        trajectory.plot(y="z")
    plt.close("all")


def test_regime_map_plot_returns_axes(rmap):
    import matplotlib.pyplot as plt

    ax = rmap.plot(title="coulomb")
    assert isinstance(ax, Axes)
    assert ax.get_title() == "coulomb"
    assert ax.get_xscale() == "log"
    plt.close("all")


def test_figure_helpers_take_library_objects(trajectory, rmap):
    fig = plotting.time_history_figure([trajectory])
    np.testing.assert_array_equal(fig.axes[0].get_lines()[0].get_ydata(), trajectory.x)
    assert "Coulomb" in fig.axes[0].get_title()
    fig = plotting.regime_maps_figure([rmap])
    assert len(fig.axes) == 1
    with pytest.raises(TypeError, match="each run must be a Trajectory or a dict"):
        plotting.time_history_figure([42])
    with pytest.raises(ValueError, match="runs is empty"):
        plotting.time_history_figure([])


def test_figures_show_as_images_in_notebooks(trajectory):
    from IPython.core.formatters import PNGFormatter

    png = PNGFormatter()(plotting.time_history_figure([trajectory]))
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


def test_human_rendering_without_a_display_warns_once():
    assert matplotlib.get_backend().lower() == "agg"
    env = gym.make("fricenv/StickSlip-v0", render_mode="human")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env.reset(seed=0)
        for _ in range(3):
            env.step(env.action_space.sample())
    shown = [w for w in caught if "render_mode='human' shows nothing" in str(w.message)]
    assert len(shown) == 1
    env.close()


def test_sb3_adapter_shows_the_vector_env_arguments():
    from fricenv.envs.sb3 import StickSlipSB3VecEnv
    from fricenv.envs.vector import StickSlipVectorEnv

    ours = inspect.signature(StickSlipSB3VecEnv).parameters
    theirs = inspect.signature(StickSlipVectorEnv).parameters
    assert list(ours) == list(theirs)
    assert all(p.kind is p.KEYWORD_ONLY or p.kind is p.POSITIONAL_OR_KEYWORD
               for p in ours.values())
    venv = StickSlipSB3VecEnv(num_envs=2, scene="self_excited", max_episode_steps=7)
    assert venv.venv.max_episode_steps == 7
    with pytest.raises(ValueError, match="SB3 needs same-step autoreset"):
        StickSlipSB3VecEnv(autoreset_mode="NextStep")


def test_run_configs_record_repository_paths(tmp_path, monkeypatch):
    from fricenv_agents.config import HYPERPARAMS_DIR
    from fricenv_agents.runs import portable_path

    assert portable_path(HYPERPARAMS_DIR / "ppo.yml") == "agents/hyperparams/ppo.yml"
    monkeypatch.chdir(tmp_path)
    assert portable_path(tmp_path / "mine.yml") == "mine.yml"
    for yml in Path(HYPERPARAMS_DIR.parent, "pretrained").glob("*.yml"):
        text = yml.read_text()
        # a machine's home or work folder, written as a pattern so this file holds none
        assert not re.search(r"/(?:work|root|home)/", text), yml.name


def test_package_ships_its_typed_marker():
    assert Path(fricenv.__file__).with_name("py.typed").is_file()
