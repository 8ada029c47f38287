"""The environments' settings record, and the vector env's public API the SB3 adapter uses."""

from __future__ import annotations

import dataclasses
import inspect
import typing

import gymnasium as gym
import numpy as np
import pytest

import fricenv  # noqa: F401  (registers the environments)
from fricenv.envs.sb3 import StickSlipSB3VecEnv
from fricenv.envs.scenes import Scene
from fricenv.envs.settings import EnvKwargs, EnvSettings
from fricenv.envs.setup import EnvSetup
from fricenv.envs.stick_slip import StickSlipEnv
from fricenv.envs.vector import StickSlipVectorEnv

SELF_ID = "fricenv/StickSlipSelfExcited-v0"
#: Settings that touch every part of the setup: scene, actions, reward, plant, sensors,
#: actuator.
SOME = EnvSettings(scene="self_excited", incremental=True, reward_weights={"effort": 0.3},
                   params={"lam": 0.06}, obs_noise=0.05, obs_delay=1, actuator_lag=0.5)


def _steps(env, n: int, seed: int) -> list[np.ndarray]:
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [obs]
    for _ in range(n):
        obs, reward, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape)
                                   .astype(np.float32))
        out.append(np.append(obs, reward))
    return out


def test_the_keyword_view_has_the_records_fields_and_types():
    record = typing.get_type_hints(EnvSettings, localns={"Scene": Scene})
    view = typing.get_type_hints(EnvKwargs, localns={"Scene": Scene})
    assert list(view) == [f.name for f in dataclasses.fields(EnvSettings)] == list(record)
    assert view == record


@pytest.mark.parametrize("cls", [StickSlipEnv, StickSlipVectorEnv, StickSlipSB3VecEnv])
def test_constructors_show_every_setting_as_a_keyword(cls):
    params = inspect.signature(cls).parameters
    for f in dataclasses.fields(EnvSettings):
        p = params[f.name]
        assert p.kind is p.KEYWORD_ONLY and p.default == f.default
    assert params["settings"].default is None
    assert not any(p.kind is p.VAR_KEYWORD for p in params.values())


def test_a_record_and_its_keywords_make_the_same_environment():
    by_record = StickSlipEnv(settings=SOME)
    by_keywords = StickSlipEnv(**SOME.as_kwargs())
    by_make = gym.make(SELF_ID, **SOME.as_kwargs())
    assert by_record.settings is SOME and by_keywords.settings == SOME
    assert by_make.unwrapped.settings == SOME
    a, b, c = (_steps(e, 5, seed=3) for e in (by_record, by_keywords, by_make))
    for x, y, z in zip(a, b, c, strict=True):
        assert np.array_equal(x, y) and np.array_equal(x, z)
    venv = StickSlipVectorEnv(num_envs=2, settings=SOME)
    sb3 = StickSlipSB3VecEnv(num_envs=2, settings=SOME)
    assert venv.settings is SOME and sb3.settings is SOME
    assert venv.single_observation_space == by_record.observation_space
    assert EnvSetup.build(SOME).settings is SOME
    assert EnvSetup.build("paper", obs_delay=2).settings == EnvSettings(obs_delay=2)


def test_setting_errors_name_the_keyword():
    with pytest.raises(TypeError, match=r"StickSlipEnv got unknown keyword argument\(s\) "
                                        r"\['obs_nosie'\]; the settings are \['scene'"):
        StickSlipEnv(obs_nosie=0.1)
    with pytest.raises(TypeError, match=r"StickSlipVectorEnv got unknown keyword"):
        StickSlipVectorEnv(num_envs=2, scne="paper")
    with pytest.raises(TypeError, match=r"StickSlipSB3VecEnv got unknown keyword"):
        StickSlipSB3VecEnv(num_envs=2, scne="paper")
    with pytest.raises(TypeError, match=r"either as settings= or as keywords, not both "
                                        r"\(got settings= and obs_delay=\)"):
        StickSlipEnv(settings=SOME, obs_delay=2)
    # gym.make passes the id's scene= itself: the message says what to do instead
    with pytest.raises(TypeError, match=r"\*\*settings.as_kwargs\(\)"):
        gym.make(SELF_ID, settings=SOME)
    with pytest.raises(TypeError, match=r"settings must be an EnvSettings or None, got dict"):
        StickSlipVectorEnv(settings={"scene": "paper"})
    with pytest.raises(TypeError, match=r"EnvSettings.replace got unknown keyword"):
        SOME.replace(sceen="paper")
    with pytest.raises(TypeError, match=r"EnvSetup.build got unknown keyword"):
        EnvSetup.build("paper", obs_nosie=0.1)
    with pytest.raises(TypeError, match=r"not both"):
        EnvSetup.build(SOME, obs_delay=1)
    # a value is checked where it is used, naming the setting
    with pytest.raises(TypeError, match="incremental must be a bool"):
        StickSlipEnv(settings=SOME.replace(incremental="no"))


def test_a_record_is_frozen_and_replace_changes_fields():
    with pytest.raises(dataclasses.FrozenInstanceError):
        SOME.obs_delay = 3  # type: ignore[misc]
    other = SOME.replace(obs_delay=3, scene="paper")
    assert other.obs_delay == 3 and other.scene == "paper" and SOME.obs_delay == 1
    assert EnvSettings().as_kwargs() == {f.name: f.default
                                         for f in dataclasses.fields(EnvSettings)}


def test_reset_plants_gives_each_plant_its_seed_and_options():
    """Plant i of ``reset_plants(seeds, options)`` starts as a single env reset with
    ``seed=seeds[i], options=options[i]``; a refused option changes no plant."""
    n = 3
    venv = StickSlipVectorEnv(num_envs=n, scene="self_excited", obs_noise=0.05)
    seeds = [4, None, 9]
    options = [{"x0": 0.5}, None, {"u0": 1.0, "nu": 0.8}]
    obs, info = venv.reset_plants([0, 1, 2], [None] * n)
    assert info == {} and obs.shape == (n, 9)
    obs, _ = venv.reset_plants(seeds, options)
    for i in (0, 2):
        single = StickSlipEnv(scene="self_excited", obs_noise=0.05)
        want, _ = single.reset(seed=seeds[i], options=options[i])
        assert np.array_equal(obs[i], want)
    assert venv.np_random_seed == (4, 1, 9)
    before = [venv.get_state(i) for i in range(n)]
    with pytest.raises(ValueError, match="lam"):
        venv.reset_plants([1, 2, 3], [None, {"lam": -1.0}, None])
    assert all(venv.get_state(i).same_as(before[i]) for i in range(n))
    assert venv.np_random_seed == (4, 1, 9)


def test_reset_plants_refuses_what_it_cannot_use():
    venv = StickSlipVectorEnv(num_envs=2)
    with pytest.raises(ValueError, match=r"seed list must have length num_envs=2"):
        venv.reset_plants([1], [None, None])
    with pytest.raises(ValueError, match=r"options must have length num_envs=2"):
        venv.reset_plants([1, 2], [None])
    with pytest.raises(TypeError, match=r"options must be a list of num_envs=2 dicts"):
        venv.reset_plants([1, 2], None)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"options\[1\] must be a dict"):
        venv.reset_plants([1, 2], [None, 5])  # type: ignore[list-item]
    with pytest.raises(ValueError, match=r"options\[0\] holds 'reset_mask'"):
        venv.reset_plants([1, 2], [{"reset_mask": np.ones(2, bool)}, None])


def test_the_sb3_adapter_reports_the_vector_envs_values_on_restarts():
    """The adapter's infos carry every plant's step values, from ``info`` or, for a plant
    whose episode ended on the step, ``final_info``: the values a single env reports."""
    n = 2
    ours = StickSlipSB3VecEnv(num_envs=n, scene="self_excited", max_episode_steps=3)
    singles = [gym.make(SELF_ID, max_episode_steps=3) for _ in range(n)]
    ours.seed(5)
    ours.reset()
    for i, env in enumerate(singles):
        env.reset(seed=5 + i)
    rng = np.random.default_rng(1)
    keys = ("stick_fraction", "effort", "velocity_variance", "mean_relative_velocity")
    for step in range(7):
        a = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        _, _, dones, infos = ours.step(a)
        for i, env in enumerate(singles):
            _, _, term, trunc, want = env.step(a[i])
            assert [infos[i][k] for k in keys] == [want[k] for k in keys], step
            assert bool(dones[i]) == (term or trunc)
            if term or trunc:
                env.reset()
