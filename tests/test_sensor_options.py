"""Sensor noise and delay per episode: the reset options ``obs_noise_scale`` and
``obs_delay``, and ``randomize_sensors``, in the single and the vector environment."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils import seeding

import fricenv  # noqa: F401  (registers the environments)
from fricenv.envs.sensors import CHANNELS
from fricenv.envs.stick_slip import StickSlipEnv
from fricenv.envs.vector import StickSlipVectorEnv

NOISE = {"x": 0.05, "v_rel": 0.1}


def _actions(env, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (n, *env.action_space.shape)).astype(np.float32)


def _rollout(env, seed, options, acts):
    obs = [env.reset(seed=seed, options=options)[0]]
    obs += [env.step(a)[0] for a in acts]
    return np.array(obs)


def test_delay_option_reads_the_line_like_an_env_made_with_that_delay():
    acts = _actions(StickSlipEnv(scene="stribeck"), 30)
    long = StickSlipEnv(scene="stribeck", obs_delay=4)
    for k in range(5):
        short = StickSlipEnv(scene="stribeck", obs_delay=k)
        assert np.array_equal(_rollout(long, 3, {"obs_delay": k}, acts),
                              _rollout(short, 3, None, acts)), k
    # no option: the configured delay again
    assert np.array_equal(_rollout(long, 3, None, acts),
                          _rollout(StickSlipEnv(scene="stribeck", obs_delay=4), 3, None, acts))


def test_noise_scale_option_scales_the_noise_and_leaves_the_episode_alone():
    acts = _actions(StickSlipEnv(scene="self_excited"), 200)
    exact = _rollout(StickSlipEnv(scene="self_excited"), 5, None, acts)
    noisy = StickSlipEnv(scene="self_excited", obs_noise=NOISE)
    fixed = _rollout(StickSlipEnv(scene="self_excited", obs_noise=NOISE), 5, None, acts)
    # scale 1 is the configured noise bit for bit; 0 is the exact observation
    assert np.array_equal(_rollout(noisy, 5, {"obs_noise_scale": 1.0}, acts), fixed)
    assert np.array_equal(_rollout(noisy, 5, {"obs_noise_scale": 0.0}, acts), exact)
    # scale 3: three times the same normals (to rounding)
    tripled = _rollout(noisy, 5, {"obs_noise_scale": 3.0}, acts)
    x = CHANNELS.index("x")
    assert np.allclose(tripled[:, x] - exact[:, x], 3 * (fixed[:, x] - exact[:, x]),
                       atol=1e-5)


def test_randomized_sensors_draw_from_the_noise_stream_as_documented():
    D = 3
    env = StickSlipEnv(scene="self_excited", obs_noise=NOISE, obs_delay=D,
                       randomize_sensors=True)
    plain = StickSlipEnv(scene="self_excited", obs_noise=NOISE, obs_delay=D)
    env.reset(seed=9)
    # the first episode's draw: the first two numbers of the noise stream, a child spawned
    # from the env's seeded generator
    child = seeding.np_random(9)[0].spawn(1)[0]
    state = env.get_state()
    assert state.noise_scale == child.random()
    assert state.obs_delay == child.integers(0, D + 1)
    # the episodes themselves are those of the env without the draws
    scales, delays = [], []
    for _ in range(60):
        env.reset()
        plain.reset(seed=9) if not scales else plain.reset()
        assert env.params == plain.params
        scales.append(env.get_state().noise_scale)
        delays.append(env.get_state().obs_delay)
    assert 0.0 <= min(scales) and max(scales) < 1.0
    assert set(delays) == set(range(D + 1))
    # options override the draw for that episode only, and the stream moves on as usual
    twin = StickSlipEnv(scene="self_excited", obs_noise=NOISE, obs_delay=D,
                        randomize_sensors=True)
    env.reset(seed=2, options={"obs_noise_scale": 0.25, "obs_delay": 1})
    twin.reset(seed=2)
    assert (env.get_state().noise_scale, env.get_state().obs_delay) == (0.25, 1)
    env.reset()
    twin.reset()
    assert env.get_state().same_as(twin.get_state())


def test_randomized_sensors_reach_the_vector_envs_autoresets():
    kw = {"obs_noise": NOISE, "obs_delay": 2, "randomize_sensors": True}
    env_id = "fricenv/StickSlip-v0"
    vec = gym.make_vec(env_id, num_envs=2, max_episode_steps=3, **kw)
    ref = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync", max_episode_steps=3,
                       **kw)
    assert np.array_equal(vec.reset(seed=4)[0], ref.reset(seed=4)[0])
    seen = set()
    for a in _actions(vec, 40):
        assert np.array_equal(vec.step(a)[0], ref.step(a)[0])
        for i in range(2):
            state = vec.unwrapped.get_state(i)
            seen.add((state.noise_scale, state.obs_delay))
    assert len(seen) > 10  # a new draw at every autoreset


def test_refused_sensor_options_are_named_and_change_nothing():
    env = StickSlipEnv(scene="paper", obs_noise=0.1, obs_delay=2)
    env.reset(seed=1)
    before = env.get_state()
    rng_state = env.np_random.bit_generator.state
    for options, err, match in (
        ({"obs_delay": 3}, ValueError, r"obs_delay.*<= 2, got 3"),
        ({"obs_delay": -1}, ValueError, "obs_delay"),
        ({"obs_delay": 1.0}, TypeError, "obs_delay"),
        ({"obs_noise_scale": -0.5}, ValueError, r"obs_noise_scale' must be >= 0, got -0.5"),
        ({"obs_noise_scale": float("nan")}, ValueError, "obs_noise_scale"),
        ({"obs_noise_scale": "loud"}, TypeError, "obs_noise_scale"),
        ({"obs_noise_scale": 0.5, "lam": -1.0}, ValueError, "lam"),
    ):
        with pytest.raises(err, match=match):
            env.reset(options=options)
        assert env.get_state().same_as(before)
        assert env.np_random.bit_generator.state == rng_state
    with pytest.raises(ValueError, match="without obs_noise"):
        StickSlipEnv(scene="paper", obs_delay=2).reset(options={"obs_noise_scale": 1.0})
    with pytest.raises(ValueError, match="<= 0, got 1"):
        StickSlipEnv(scene="paper").reset(options={"obs_delay": 1})
    StickSlipEnv(scene="paper").reset(options={"obs_delay": 0})  # the only delay there is
    vec = StickSlipVectorEnv(num_envs=2, obs_noise=0.1, obs_delay=2)
    vec.reset(seed=0)
    states = [vec.get_state(i) for i in range(2)]
    with pytest.raises(ValueError, match="obs_delay"):
        vec.reset(options={"obs_delay": 5})
    assert all(vec.get_state(i).same_as(s) for i, s in enumerate(states))


def test_randomize_sensors_is_checked():
    with pytest.raises(ValueError, match="needs obs_noise or obs_delay"):
        StickSlipEnv(scene="paper", randomize_sensors=True)
    with pytest.raises(TypeError, match="randomize_sensors"):
        StickSlipEnv(scene="paper", obs_delay=1, randomize_sensors="yes")
    env = StickSlipEnv(scene="paper", obs_delay=1, randomize_sensors=True)
    assert env.setup.instruments.describe()["randomize_sensors"] is True


def test_set_state_carries_and_checks_the_scale_and_delay():
    kw = {"scene": "viscous", "obs_noise": NOISE, "obs_delay": 3}
    env = StickSlipEnv(**kw)
    env.reset(seed=0, options={"obs_noise_scale": 0.3, "obs_delay": 1})
    acts = _actions(env, 12)
    for a in acts[:5]:
        env.step(a)
    state = env.get_state()
    assert (state.noise_scale, state.obs_delay) == (0.3, 1)
    first = [env.step(a)[0] for a in acts[5:]]
    other = StickSlipEnv(**kw)
    other.reset(seed=1)  # its own episode: scale 1, delay 3
    other.set_state(state)
    assert all(np.array_equal(other.step(a)[0], f) for a, f in zip(acts[5:], first, strict=True))
    vec = StickSlipVectorEnv(num_envs=2, **kw)
    vec.reset(seed=5)
    vec.set_state(0, state)
    restored = vec.get_state(0)
    assert (restored.noise_scale, restored.obs_delay) == (0.3, 1)
    for a, f in zip(acts[5:], first, strict=True):
        assert np.array_equal(vec.step(np.stack([a, a]))[0][0], f)
    from dataclasses import replace
    for bad, match in ((replace(state, obs_delay=4), "obs_delay"),
                       (replace(state, noise_scale=-1.0), "noise_scale"),
                       (replace(state, noise_scale=float("inf")), "noise_scale")):
        with pytest.raises(ValueError, match=match):
            env.set_state(bad)


def test_agents_yml_env_kwargs_reach_the_sb3_env():
    import yaml

    from agents.config import split_hyperparams
    from agents.envs import make_sb3_env

    hp = yaml.safe_load("""
n_envs: 2
env_kwargs: {obs_noise: {x: 0.05}, obs_delay: 1, randomize_sensors: true}
""")
    spec = split_hyperparams("ppo", hp)
    venv = make_sb3_env("paper", spec.n_envs, 0, spec.env_kwargs)
    venv.reset()
    inner = venv.venv.venv
    assert inner.settings.randomize_sensors is True and inner.settings.obs_delay == 1
    assert {inner.get_state(i).obs_delay for i in range(2)} <= {0, 1}
