"""Gymnasium environments: API conformance, determinism, vector equivalence, SB3 training."""

from __future__ import annotations

import math
import subprocess
import sys
import warnings

import gymnasium as gym
import numba
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import fricenv  # noqa: F401  (registers the environments once fricenv/__init__ calls it)
from fricenv.envs import ENV_IDS, register_envs
from fricenv.envs.scenes import SCENES, Scene
from fricenv.envs.stick_slip import StickSlipEnv
from fricenv.envs.vector import DRAW_ROWS, StickSlipVectorEnv

register_envs()  # idempotent; keeps this file independent of fricenv/__init__

ENV_ID = "fricenv/StickSlip-v0"
SELF_ID = "fricenv/StickSlipSelfExcited-v0"


def _no_warnings(fn, *args, allow: str | None = None, **kwargs):
    """Run ``fn``, asserting it warns nothing (but messages starting with ``allow``)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn(*args, **kwargs)
    caught = [w for w in caught if allow is None or not str(w.message).startswith(allow)]
    assert not caught, [str(w.message) for w in caught]


def _rollout(env, seed, n, action_seed=0, options=None):
    obs, _ = env.reset(seed=seed, options=options)
    rng = np.random.default_rng(action_seed)
    out = [obs]
    for _ in range(n):
        a = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        obs, r, term, trunc, info = env.step(a)
        out.append(np.concatenate([obs, [r, term, trunc, info["stick_fraction"], info["effort"]]]))
    return out


# -- registration and API checks -----------------------------------------------------------
def test_registration_and_make():
    for env_id, scene in ENV_IDS.items():
        spec = gym.spec(env_id)
        assert spec.kwargs["scene"] == scene
        assert spec.max_episode_steps == SCENES[scene].max_episode_steps
        assert spec.vector_entry_point == "fricenv.envs.vector:StickSlipVectorEnv"
    env = gym.make(ENV_ID, action_mode="both")
    assert isinstance(env.unwrapped, StickSlipEnv)
    assert env.action_space.shape == (2,) and env.action_space.dtype == np.float32
    assert env.observation_space.shape == (9,) and env.observation_space.dtype == np.float32
    assert np.all(np.isfinite(env.observation_space.low))
    assert np.all(np.isfinite(env.observation_space.high))
    register_envs()  # a second call neither fails nor warns
    vec = gym.make_vec(ENV_ID, num_envs=3)
    assert isinstance(vec, StickSlipVectorEnv)
    assert vec.max_episode_steps == 200


def test_docstring_has_gymnasium_sections():
    doc = StickSlipEnv.__doc__
    for section in (
        "Description",
        "Action Space",
        "Observation Space",
        "Rewards",
        "Starting State",
        "Episode End",
        "Arguments",
        "Version History",
    ):
        assert f"## {section}" in doc


@pytest.mark.parametrize("env_id", [ENV_ID, SELF_ID])
def test_gymnasium_check_env(env_id):
    from gymnasium.utils.env_checker import check_env

    env = gym.make(env_id, action_mode="both", randomize=True)
    # includes the rgb_array and human render checks; on this headless backend the human
    # check may only say that it cannot show anything
    _no_warnings(check_env, env.unwrapped, allow="render_mode='human' shows nothing")


def test_sb3_check_env():
    from stable_baselines3.common.env_checker import check_env

    for mode in ("amplitude", "frequency", "both"):
        _no_warnings(check_env, gym.make(ENV_ID, action_mode=mode), warn=True)


def test_spaces_follow_scene_ranges():
    env = gym.make(SELF_ID, action_mode="amplitude", incremental=True)
    sc = SCENES["self_excited"]
    low, high = env.observation_space.low, env.observation_space.high
    assert (low[7], high[7]) == pytest.approx(sc.u0_range)
    assert (low[8], high[8]) == pytest.approx(sc.nu_range)
    assert env.action_space.shape == (1,)


# -- determinism, options, randomisation -----------------------------------------------------
def test_seeded_runs_are_identical():
    kw = dict(action_mode="both", randomize=True, incremental=True)
    a = _rollout(gym.make(SELF_ID, **kw), seed=11, n=60)
    b = _rollout(gym.make(SELF_ID, **kw), seed=11, n=60)
    c = _rollout(gym.make(SELF_ID, **kw), seed=12, n=60)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_reset_options_override_one_episode_without_shifting_the_stream():
    env = gym.make(ENV_ID).unwrapped
    opts = {"x0": 0.0, "v0": 0.0, "phi1": 0.0, "phi2": 0.0, "lam": 0.3, "u0": 1.0}
    obs, _ = env.reset(seed=5, options=opts)
    assert obs[0] == 0.0 and obs[1] == -1.0  # x = 0, v - V = -1: the paper's start from rest
    assert obs[3] == 1.0 and obs[4] == 0.0 and obs[7] == 1.0
    assert env.params["lam"] == 0.3
    second = env.reset()[0]
    assert env.params["lam"] == 0.5 and env.params["u0"] == 2.0  # only that episode
    env.reset(seed=5)
    assert np.array_equal(env.reset()[0], second)  # options consumed no extra draws
    for bad in ({"lam": -1.0}, {"mass": 1.0}, {"u0": 99.0}, {"x0": float("nan")}):
        with pytest.raises(ValueError):
            env.reset(options=bad)


def test_randomisation_stays_in_the_scene_ranges():
    env = gym.make(SELF_ID, randomize=True).unwrapped
    ranges = SCENES["self_excited"].ranges
    seen = []
    for seed in range(20):
        env.reset(seed=seed)
        p = env.params
        for key, (lo, hi) in ranges.items():
            assert lo <= p[key] <= hi
        seen.append(p["lam"])
    assert len(set(seen)) == 20
    env = gym.make(SELF_ID).unwrapped
    env.reset(seed=0)
    assert env.params["lam"] == SCENES["self_excited"].params.lam


def test_params_are_checked_against_the_ranges_only_when_randomising():
    """params={"xfs": 2.5} makes the valid x_fs = x_fk plant; without randomize, x_fk's
    range (2.2, 2.8) is never drawn from, so it must not refuse it (it did, with the
    puzzling "xfs must be >= xfk = 2.8"). With randomize, the clash is named."""
    env = gym.make(ENV_ID, params={"xfs": 2.5}).unwrapped
    env.reset(seed=0)
    assert env.params["xfk"] == env.params["xfs"] == 2.5
    for _ in range(20):
        env.step(env.action_space.sample())
    vec = StickSlipVectorEnv(num_envs=2, scene="self_excited", params={"xfs": 2.5})
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=r"randomization corner .*'xfk': 2\.8.*xfs must be >= xfk"):
        gym.make(ENV_ID, params={"xfs": 2.5}, randomize=True)


def test_scene_validation():
    sc = SCENES["paper"]
    with pytest.raises(ValueError):
        sc.replace(u0_range=(1.0, 0.5))
    with pytest.raises(ValueError):
        sc.replace(randomization={"xfk": (2.0, 4.5)})  # could exceed xfs
    with pytest.raises(ValueError):
        sc.replace(randomization={"mass": (1.0, 2.0)})
    with pytest.raises(ValueError, match=r"u0_range must lie within \+-1e\+12.* 1e\+200"):
        sc.replace(u0_range=(0.0, 1e200))  # actions could reach an unphysical amplitude
    with pytest.raises(ValueError, match=r"nu_range must lie within"):
        sc.replace(nu_range=(0.1, 1e13))
    with pytest.raises(ValueError, match=r"x0_range must lie within"):
        sc.replace(x0_range=(-1e13, 0.0))  # a start whose square overflows the reward
    with pytest.raises(ValueError, match=r"randomization\['V'\] must lie within"):
        sc.replace(randomization={"V": (1.0, 1e200)})
    with pytest.raises(ValueError):
        gym.make(ENV_ID, scene="nope")
    with pytest.raises(ValueError):
        gym.make(ENV_ID, action_mode="phase")
    assert isinstance(sc.replace(max_episode_steps=10), Scene)


# -- dynamics seen through the env ----------------------------------------------------------
def test_reward_formula_range_and_info():
    env = gym.make(SELF_ID, action_mode="both", reward_weights={"effort": 0.3}).unwrapped
    ws, wv, we = env.scene.reward_weights
    assert we == 0.3
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    for _ in range(100):
        obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        s, e, q = info["stick_fraction"], info["effort"], info["velocity_variance"]
        assert 0.0 <= s <= 1.0 and 0.0 <= e <= 1.0 and q >= 0.0
        V = env.params["V"]
        assert r == pytest.approx(-(ws * s + wv * q / (q + V * V) + we * e), rel=1e-12)
        assert -(ws + wv + we) <= r <= 0.0
        assert e == pytest.approx((obs[7] / env.scene.u0_range[1]) ** 2, rel=1e-6)
        assert not term and not trunc
        assert obs[2] in (0.0, 1.0)


def test_mean_relative_velocity_and_interval_sampling():
    """info's interval mean of v - V is the displacement's rate minus V; sample_interval
    previews exactly what the next step integrates and leaves the environment untouched."""
    env = gym.make(ENV_ID, action_mode="both").unwrapped
    env.reset(seed=4)
    rng = np.random.default_rng(2)
    for _ in range(20):
        a = rng.uniform(-1, 1, 2).astype(np.float32)
        before = env.snapshot()
        t, v_rel, stuck = env.sample_interval(a, 50)
        assert env.snapshot() == before
        assert t.shape == v_rel.shape == stuck.shape == (50,) and stuck.dtype == np.bool_
        np.testing.assert_allclose(t, before["t"] + env.dt * np.arange(1, 51) / 50, rtol=1e-12)
        info = env.step(a)[4]
        after = env.snapshot()
        assert v_rel[-1] == pytest.approx(after["v"] - after["V"], abs=1e-9)
        assert info["mean_relative_velocity"] == pytest.approx(
            (after["x"] - before["x"]) / env.dt - before["V"], abs=1e-12)
    with pytest.raises(ValueError, match="n_samples"):
        env.sample_interval(np.zeros(2, np.float32), 0)
    with pytest.raises(TypeError, match="n_samples"):  # a count: 2.5 is the wrong type
        env.sample_interval(np.zeros(2, np.float32), 2.5)
    with pytest.raises(ValueError, match="finite"):
        env.sample_interval(np.array([np.nan, 0.0], np.float32))
    fresh = gym.make(ENV_ID).unwrapped
    with pytest.raises(gym.error.ResetNeeded):
        fresh.sample_interval(np.zeros(1, np.float32))


def test_self_excited_scene_sticks_unforced_and_can_be_quenched():
    def mean_stick(u_action):
        env = gym.make(SELF_ID, action_mode="amplitude").unwrapped
        env.reset(seed=0)
        fr = [env.step(np.array([u_action], np.float32))[4]["stick_fraction"] for _ in range(300)]
        return float(np.mean(fr[150:]))

    assert mean_stick(-1.0) > 0.25  # u0 = 0: self-excited stick-slip
    assert mean_stick(1.0) < 0.05  # u0 = 2 on both tones (nu = 1): quenched


def test_retuning_keeps_phases_continuous():
    env = gym.make(ENV_ID, action_mode="both").unwrapped
    env.reset(seed=3, options={"phi1": 0.0, "phi2": 0.0})
    nlo, nhi = env.scene.nu_range
    eta, dt = env.params["eta"], env.dt
    phase2 = 0.0
    for a_nu in (-1.0, 0.5, 1.0, -0.3):
        nu = nlo + 0.5 * (a_nu + 1.0) * (nhi - nlo)
        before = env.snapshot()
        obs = env.step(np.array([0.2, a_nu], np.float32))[0]
        phase2 += nu * eta * dt
        # tone 2's phase advanced by nu * eta * dt from where it was: no phase jump
        assert obs[5] == pytest.approx(math.cos(phase2), abs=1e-6)
        assert obs[6] == pytest.approx(math.sin(phase2), abs=1e-6)
        assert before["t"] + dt == pytest.approx(env.snapshot()["t"])


def test_incremental_actions_move_by_at_most_max_delta():
    env = gym.make(ENV_ID, action_mode="both", incremental=True).unwrapped
    obs, _ = env.reset(seed=0)
    sc = env.scene
    du = sc.max_delta * (sc.u0_range[1] - sc.u0_range[0])
    dnu = sc.max_delta * (sc.nu_range[1] - sc.nu_range[0])
    prev = obs
    for a in ([1, 1], [5, -5], [-0.5, 0.25], [-1, -1]):
        obs = env.step(np.array(a, np.float32))[0]
        assert abs(obs[7] - prev[7]) <= du + 1e-6 and abs(obs[8] - prev[8]) <= dnu + 1e-6
        prev = obs
    assert obs[7] == pytest.approx(2.0 + 0.5 * du, abs=1e-5)  # +1, +1 (clipped), -0.5, -1


def test_termination_only_when_leaving_the_observation_box():
    small = SCENES["paper"].replace(x_limit=3.0)
    env = StickSlipEnv(scene=small)
    env.reset(seed=0, options={"x0": 2.9, "v0": 5.0})
    obs, _, term, trunc, _ = env.step(np.zeros(1, np.float32))
    assert term and not trunc and obs[0] == np.float32(3.0)


def test_truncation_comes_from_time_limit_only():
    env = gym.make(ENV_ID, max_episode_steps=5)
    env.reset(seed=0)
    flags = [env.step(env.action_space.sample())[3] for _ in range(5)]
    assert flags == [False] * 4 + [True]
    raw = env.unwrapped
    raw.reset(seed=0)
    assert not any(raw.step(raw.action_space.sample())[3] for _ in range(300))


# -- bad input ------------------------------------------------------------------------------
def test_nan_action_raises_value_error_and_leaves_state_alone():
    env = gym.make(ENV_ID, action_mode="both").unwrapped
    env.reset(seed=0)
    snap = env.snapshot()
    for bad in ([np.nan, 0.0], [0.0, np.inf]):
        with pytest.raises(ValueError):
            env.step(np.array(bad, np.float32))
    assert env.snapshot() == snap
    env.step(np.zeros(2, np.float32))  # still usable
    with pytest.raises(ValueError):
        env.step(np.zeros(3))
    env.step([0.1, -0.1])  # lists are accepted

    vec = StickSlipVectorEnv(num_envs=3, action_mode="both")
    vec.reset(seed=0)
    a = np.zeros((3, 2), np.float32)
    a[2, 1] = np.nan
    obs = vec._obs.copy()
    with pytest.raises(ValueError, match="action 2"):
        vec.step(a)
    assert np.array_equal(vec._obs, obs)


def test_step_before_reset_raises():
    with pytest.raises(gym.error.ResetNeeded):
        StickSlipEnv().step(np.zeros(1, np.float32))


@pytest.mark.parametrize("bad", [None, "abc", "0.5", {"a": 1}, [None], 1 + 1j])
def test_non_numeric_action_raises_type_error_naming_it(bad):
    # None used to become NaN ("must be finite"), "0.5" a number, complex a warning
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    msg = r"must be an array of real numbers of shape"
    with pytest.raises(TypeError, match=r"action " + msg + r" \(1,\)"):
        env.step(bad)
    with pytest.raises(TypeError, match=r"action must be an array of real numbers"):
        env.unwrapped.sample_interval(bad)
    vec = gym.make_vec(ENV_ID, num_envs=4)
    vec.reset(seed=0)
    with pytest.raises(TypeError, match=r"actions " + msg + r" \(4, 1\)"):
        vec.step(bad)
    env.step(np.zeros(1, np.float32))  # both still usable
    vec.step(np.zeros((4, 1), np.float32))


def test_bool_actions_are_refused():
    env = StickSlipEnv()
    env.reset(seed=0)
    with pytest.raises(TypeError, match=r"action must be an array of real numbers.*\(bool\)"):
        env.step(True)


def test_action_of_wrong_size_raises_value_error_naming_the_shape():
    env = gym.make(ENV_ID)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(1,\), got shape \(2,\): \[0.0, 0.0\]"):
        env.step([0.0, 0.0])
    vec = StickSlipVectorEnv(num_envs=4)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions .* shape \(4, 1\), got shape \(\)"):
        vec.step(0.0)
    with pytest.raises(ValueError, match=r"actions must be an array of real numbers"):
        vec.step([[0.0], [0.0, 1.0]])  # ragged


@pytest.mark.parametrize("dtype", [np.float16, np.longdouble, ">f8", ">f4", np.int64])
def test_actions_of_other_dtypes_step_like_float64(dtype):
    # float16, long double and byte-swapped arrays used to reach numba (typing errors)
    a, b = StickSlipEnv(action_mode="both"), StickSlipEnv(action_mode="both")
    a.reset(seed=3)
    b.reset(seed=3)
    act = np.array([1.0, -1.0])  # exact in every dtype
    assert np.array_equal(a.step(act.astype(dtype))[0], b.step(act)[0])
    va, vb = StickSlipVectorEnv(num_envs=2), StickSlipVectorEnv(num_envs=2)
    va.reset(seed=3)
    vb.reset(seed=3)
    acts = np.array([[1.0], [-1.0]])
    assert np.array_equal(va.step(acts.astype(dtype))[0], vb.step(acts)[0])


def test_numpy_integer_seeds_seed_like_python_ints():
    """Gymnasium's Env.reset takes only Python ints; numpy ints come from seed arrays and
    from SB3's VecEnv.seed (seed + index)."""
    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    env = StickSlipEnv()
    assert np.array_equal(env.reset(seed=np.int64(3))[0], env.reset(seed=3)[0])
    ours = StickSlipSB3VecEnv(num_envs=2)
    ours.seed(np.int64(3))
    first = ours.reset()
    ours.seed(3)
    assert np.array_equal(first, ours.reset())


def test_complex_reset_options_are_refused():
    env = StickSlipEnv()
    with pytest.raises(TypeError, match="reset option 'u0' must be a real number"):
        env.reset(seed=0, options={"u0": np.complex128(1 + 1j)})  # was cut to 1.0


def test_vector_reset_options_are_checked_before_reseeding():
    vec = StickSlipVectorEnv(num_envs=2)
    vec.reset(seed=1)
    state = vec.np_random.bit_generator.state
    with pytest.raises(TypeError, match="options must be a dict"):
        vec.reset(seed=7, options=5)
    assert vec.np_random.bit_generator.state == state


def test_a_rejected_reset_loses_nothing():
    """Neither a reseed nor a draw survives a reset that raises: the next reset is the one
    an untouched twin makes (options are checked against drawn values, so the draw is
    undone rather than avoided)."""
    env, twin = StickSlipEnv(), StickSlipEnv()
    env.reset(seed=5)
    twin.reset(seed=5)
    with pytest.raises(ValueError, match="lam"):
        env.reset(options={"lam": -1.0})
    with pytest.raises(ValueError, match="u0"):
        env.reset(seed=99, options={"u0": 99.0})
    assert np.array_equal(env.reset()[0], twin.reset()[0])

    vec, twin = StickSlipVectorEnv(num_envs=3), StickSlipVectorEnv(num_envs=3)
    vec.reset(seed=1)
    twin.reset(seed=1)
    state = vec.np_random.bit_generator.state
    # a fresh seed refills every plant's buffer before the options fail: all is put back
    with pytest.raises(ValueError, match="lam"):
        vec.reset(seed=7, options={"lam": -1.0})
    with pytest.raises(TypeError, match=r"reset_mask.*got \[True, False, True\] \(list\)"):
        vec.reset(seed=7, options={"reset_mask": [True, False, True]})
    with pytest.raises(gym.error.Error, match="Seed must be greater or equal to zero"):
        vec.reset(seed=[0, 1, -1])  # plants 0 and 1 are not reseeded either
    assert vec.np_random.bit_generator.state == state
    assert np.array_equal(vec.reset()[0], twin.reset()[0])
    for env in (vec, twin):  # spent buffers, as a step that raised after autoresets leaves
        env._cursor[:] = DRAW_ROWS
    with pytest.raises(ValueError, match="lam"):
        vec.reset(options={"lam": -1.0})
    assert np.array_equal(vec.reset()[0], twin.reset()[0])


def test_exact_method_is_refused_only_when_episodes_can_leave_the_coulomb_law():
    scene = SCENES["paper"].replace(randomization={"b1": (0.0, 0.2)})
    env = StickSlipEnv(scene=scene, method="exact")  # randomize=False: b1 = 0 always
    env.reset(seed=0)
    env.step(np.zeros(1, np.float32))
    with pytest.raises(ValueError, match="method='exact' needs the Coulomb law"):
        StickSlipEnv(scene=scene, randomize=True, method="exact")
    with pytest.raises(ValueError, match="method='exact' needs the Coulomb law"):
        StickSlipVectorEnv(num_envs=2, scene=scene, randomize=True, method="exact")


def test_vector_actions_must_be_one_row_per_plant():
    vec = StickSlipVectorEnv(num_envs=3, action_mode="both")
    vec.reset(seed=0)
    obs = vec._obs.copy()
    # transposed: as many values, but read as other plants' actions it would be accepted
    with pytest.raises(ValueError, match=r"shape \(3, 2\), got shape \(2, 3\)"):
        vec.step(np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"got shape \(6,\)"):
        vec.step(np.zeros(6))
    a = np.asfortranarray(np.zeros((3, 2)))  # the slow path, then the kernel's check
    a[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"action 2 must be finite.*got array\(\[ 0., nan\]\)"):
        vec.step(a)
    assert np.array_equal(vec._obs, obs)
    flat, twin = StickSlipVectorEnv(num_envs=3), StickSlipVectorEnv(num_envs=3)
    flat.reset(seed=0)  # (3, 1): one value per plant may come flat
    twin.reset(seed=0)
    assert np.array_equal(flat.step([0.5, -0.5, 0.0])[0], twin.step(np.c_[[0.5, -0.5, 0.0]])[0])


def test_vector_reset_seed_of_wrong_type_or_length_raises():
    vec = gym.make_vec(ENV_ID, num_envs=4)
    with pytest.raises(TypeError, match=r"seed must be an int, a list of num_envs=4 .* got 1\.5"):
        vec.reset(seed=1.5)
    with pytest.raises(TypeError, match=r"seed must be an int.* got 'abcd' \(str\)"):
        vec.reset(seed="abcd")
    with pytest.raises(TypeError, match=r"seed\[1\] must be an int or None, got 2\.0"):
        vec.reset(seed=[0, 2.0, None, 3])
    with pytest.raises(ValueError, match=r"seed list must have length num_envs=4, got 2 seeds"):
        vec.reset(seed=[0, 1])
    obs, _ = vec.reset(seed=np.arange(4))  # numpy integers are ints
    assert np.array_equal(obs, vec.reset(seed=(0, 1, 2, 3))[0])


def test_reward_weights_must_be_three_weights_or_a_dict():
    msg = r"reward_weights must be three weights \(w_stick, w_velocity, w_effort\) or a dict"
    with pytest.raises(TypeError, match=msg + r".* got 1\.0 \(float\)"):
        gym.make(ENV_ID, reward_weights=1.0)
    with pytest.raises(TypeError, match=msg):
        StickSlipVectorEnv(reward_weights=1.0)
    with pytest.raises(ValueError, match=msg + r".* got 2 values"):
        StickSlipEnv(reward_weights=(1.0, 0.5))
    with pytest.raises(TypeError, match=r"reward_weights\['stick'\] must be a real number"):
        StickSlipEnv(reward_weights={"stick": "high"})
    with pytest.raises(ValueError, match="unknown reward weight"):
        StickSlipEnv(reward_weights={"sticky": 1.0})
    assert StickSlipEnv(reward_weights={"stick": 2}).scene.reward_weights == (2.0, 0.5, 0.1)
    assert StickSlipEnv(reward_weights=[1, 0, 0]).scene.reward_weights == (1.0, 0.0, 0.0)


_PAPER = SCENES["paper"]


@pytest.mark.parametrize(
    "make, error, match",
    [
        (lambda: StickSlipEnv(params=0.2), TypeError,
         r"params must be a dict .* got 0\.2 \(float\)"),
        (lambda: StickSlipEnv(scene=5), TypeError, r"scene must be a scene name or a Scene, got 5"),
        (lambda: StickSlipEnv(control_dt="fast"), TypeError,
         r"control_dt must be a real number, got 'fast'"),
        (lambda: StickSlipEnv(method=["exact"]), TypeError, r"method must be one of"),
        (lambda: StickSlipVectorEnv(num_envs=2.5), TypeError,
         r"num_envs must be an integer, got 2\.5"),
        (lambda: StickSlipVectorEnv(num_envs=0), ValueError,
         r"num_envs must be an integer >= 1, got 0"),
        (lambda: StickSlipVectorEnv(max_episode_steps="10"), TypeError,
         r"max_episode_steps must be an integer, got '10'"),
        (lambda: StickSlipEnv().reset(options=5), TypeError,
         r"options must be a dict or None, got 5 \(int\)"),
        (lambda: StickSlipVectorEnv(num_envs=2).reset(options=5), TypeError,
         r"options must be a dict or None, got 5 \(int\)"),
        (lambda: _PAPER.replace(u0_range=4.0), TypeError,
         r"u0_range must be a finite \(lo, hi\).* got 4\.0"),
        (lambda: _PAPER.replace(tone_gains=(1.0, None)), TypeError,
         r"tone_gains\[1\] must be a real number, got None"),
        (lambda: _PAPER.replace(randomization={"lam": 0.5}), TypeError,
         r"randomization\['lam'\] must be a finite \(lo, hi\)"),
        # a list of names gave a raw "dictionary update sequence" error from dict()
        (lambda: _PAPER.replace(randomization=["lam"]), TypeError,
         r"randomization must be a dict \{param: \(lo, hi\)\} or None, got \['lam'\] \(list\)"),
        (lambda: _PAPER.replace(randomization=[("lam", (0.4, 0.6))]), TypeError,
         r"randomization must be a dict .* got \[\('lam', \(0\.4, 0\.6\)\)\] \(list\)"),
        (lambda: _PAPER.replace(randomization={"lam": None}), TypeError,
         r"randomization\['lam'\] must be a finite \(lo, hi\) with lo <= hi, got None"),
        (lambda: _PAPER.replace(randomization={"lam": ("a", 0.6)}), TypeError,
         r"randomization\['lam'\]\[0\] must be a real number, got 'a' \(str\)"),
        (lambda: _PAPER.replace(randomization={"lam": (0.4, 0.5, 0.6)}), ValueError,
         r"randomization\['lam'\] must be a finite \(lo, hi\) .* got 3 values: \(0\.4"),
        (lambda: _PAPER.replace(randomization={"lam": (0.6, 0.4)}), ValueError,
         r"randomization\['lam'\] must be a finite \(lo, hi\) with lo <= hi, got \(0\.6"),
        (lambda: _PAPER.replace(params={"lam": 0.2}), TypeError,
         r"params must be an OscillatorParams, got \{'lam': 0\.2\} \(dict\)"),
        (lambda: _PAPER.replace(action_mode=["both"]), TypeError,
         r"action_mode must be one of .* got \['both'\] \(list\)"),
        (lambda: _PAPER.replace(random_phase="no"), TypeError,
         r"random_phase must be a bool .* got 'no' \(str\)"),
        # a truthy string switched incremental actions on
        (lambda: StickSlipEnv(incremental="no"), TypeError,
         r"incremental must be a bool \(True or False\), got 'no' \(str\)"),
        (lambda: StickSlipVectorEnv(incremental="no"), TypeError,
         r"incremental must be a bool \(True or False\), got 'no' \(str\)"),
        (lambda: gym.make(ENV_ID, incremental=1), TypeError,
         r"incremental must be a bool \(True or False\), got 1 \(int\)"),
        (lambda: StickSlipEnv(randomize="yes"), TypeError,
         r"randomize must be a bool \(True or False\), got 'yes' \(str\)"),
        # a non-number in reset options was a ValueError; NaN and bad values still are
        (lambda: StickSlipEnv().reset(options={"lam": "0.3"}), TypeError,
         r"reset option 'lam' must be a real number, got '0\.3' \(str\)"),
        (lambda: StickSlipEnv().reset(options={"x0": None}), TypeError,
         r"reset option 'x0' must be a real number, got None \(NoneType\)"),
        (lambda: StickSlipVectorEnv(num_envs=2).reset(options={"nu": [1.0]}), TypeError,
         r"reset option 'nu' must be a real number, got \[1\.0\] \(list\)"),
        (lambda: StickSlipEnv().reset(options={"x0": math.nan}), ValueError,
         r"reset option 'x0' must be finite, got nan"),
        (lambda: StickSlipEnv().reset(options={"lam": -1.0}), ValueError,
         r"lam must be >= 0, got -1\.0"),
    ],
)
def test_constructor_and_reset_arguments_of_wrong_type_raise(make, error, match):
    with pytest.raises(error, match=match):
        make()


def test_bool_arguments_take_numpy_bools_and_scene_randomization_round_trips():
    env = StickSlipEnv(incremental=np.bool_(True), randomize=np.bool_(False))
    assert env.setup.incremental is True and env.setup.randomize is False
    sc = _PAPER.replace(randomization={"lam": (0.4, 0.7)}, random_phase=np.bool_(False))
    assert sc.ranges == {"lam": (0.4, 0.7)} and sc.random_phase is False
    assert sc.replace(name="copy").ranges == sc.ranges  # the stored pairs are taken back
    assert _PAPER.replace(randomization=None).ranges == {}


_SLOW = r"scan steps over a span of 0\.523599 \(at most 1e\+06\)"


@pytest.mark.parametrize("vector", [False, True])
def test_reset_options_needing_too_many_scan_steps_per_interval_are_refused(vector):
    """reset(options={"lam": 1e8}) made every step take ~3 s: the over-damped plant's scan
    step is 1 / lam, so a control interval took 5e7 of them."""
    env = StickSlipVectorEnv(num_envs=2) if vector else StickSlipEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=_SLOW + r".*\(lam = 1e\+08\).*refused reset options"):
        env.reset(options={"lam": 1e8})
    # a tone that fast: eta at 1e7 and nu at the top of its range (the action can reach it)
    with pytest.raises(ValueError, match=_SLOW + r".*\(eta = 1e\+07, nu \* eta = 2e\+07\)"):
        env.reset(options={"eta": 1e7, "nu": 0.1})
    env.reset(options={"lam": 1e5})  # stiff, but within the cap: it runs
    a = np.zeros((2, 1) if vector else (1,), np.float32)
    assert np.all(np.isfinite(env.step(a)[0]))


def test_plants_needing_too_many_scan_steps_per_interval_are_refused_at_construction():
    with pytest.raises(ValueError, match=_SLOW + r".*\(lam = 1e\+08\).*scene's plant"):
        StickSlipEnv(params={"lam": 1e8})
    with pytest.raises(ValueError, match=r"\(lam = 1e\+08\)"):
        StickSlipVectorEnv(num_envs=2, params={"lam": 1e8})
    # The vector env autoresets inside its kernel from draws of the randomisation ranges,
    # with no Python check: the ranges' worst corner is checked when the env is built.
    wide = _PAPER.replace(randomization={"lam": (0.4, 1e8)})
    for make in (StickSlipEnv, lambda **kw: StickSlipVectorEnv(num_envs=2, **kw)):
        with pytest.raises(ValueError, match=r"\(lam = 1e\+08\).*fastest plant"):
            make(scene=wide, randomize=True)
        make(scene=wide, randomize=False).reset(seed=0)  # the nominal plant alone is fine
    fast = _PAPER.replace(randomization={"eta": (0.5, 1e7)})
    with pytest.raises(ValueError, match=r"\(eta = 1e\+07, nu \* eta = 2e\+07\)"):
        StickSlipVectorEnv(num_envs=2, scene=fast, randomize=True)
    # in amplitude mode nu keeps its start (0.1), so the same eta is 10x slower, still too slow
    with pytest.raises(ValueError, match=r"nu \* eta = 1e\+06\).* at u0 = 4, nu = 0\.1;"):
        StickSlipEnv(scene=fast, randomize=True, action_mode="amplitude")
    # a silent plant does not bound the step: u0 = 0 and only nu driven
    silent = _PAPER.replace(params=_PAPER.params.replace(u0=0.0, eta=1e7))
    StickSlipEnv(scene=silent, action_mode="frequency").reset(seed=0)
    with pytest.raises(ValueError, match=r"eta = 1e\+07.*at u0 = 1, nu = 2"):
        StickSlipEnv(scene=silent, action_mode="frequency").reset(options={"u0": 1.0})


# -- native vector env ----------------------------------------------------------------------
def _assert_same_step(r1, r2):
    for x, y in zip(r1[:4], r2[:4], strict=True):
        assert x.dtype == y.dtype and np.array_equal(x, y)
    i1, i2 = r1[4], r2[4]
    assert i1.keys() == i2.keys()
    for key in i1:
        if key == "final_obs":
            for x, y in zip(i1[key], i2[key], strict=True):
                assert (x is None and y is None) or np.array_equal(x, y)
        elif key == "final_info":
            assert i1[key].keys() == i2[key].keys()
            for k in i1[key]:
                assert np.array_equal(i1[key][k], i2[key][k])
        else:
            assert i1[key].dtype == i2[key].dtype and np.array_equal(i1[key], i2[key]), key


def _native_and_sync(n, horizon, mode, **kw):
    """The native vector env and its reference: SyncVectorEnv over gym.make'd single envs
    (TimeLimit, seeds seed + i), both with this horizon and autoreset mode."""
    native = gym.make_vec(ENV_ID, num_envs=n, max_episode_steps=horizon, autoreset_mode=mode, **kw)
    singles = gym.make_vec(
        ENV_ID,
        num_envs=n,
        vectorization_mode="sync",
        max_episode_steps=horizon,
        vector_kwargs={"autoreset_mode": mode},
        **kw,
    )
    return native, singles


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
@pytest.mark.parametrize(
    "kw",
    [{}, {"scene": "self_excited", "randomize": True, "action_mode": "both", "incremental": True}],
)
def test_vector_env_matches_single_envs_step_for_step(mode, kw):
    native, singles = _native_and_sync(4, 7, mode, **kw)  # short episodes: many autoresets
    assert isinstance(native, StickSlipVectorEnv)
    assert native.metadata["autoreset_mode"] == mode
    o1, _ = native.reset(seed=42)
    o2, _ = singles.reset(seed=42)
    assert np.array_equal(o1, o2)
    rng = np.random.default_rng(0)
    for _ in range(25):
        a = rng.uniform(-1.2, 1.2, native.action_space.shape).astype(np.float32)
        _assert_same_step(native.step(a), singles.step(a))
    o1, _ = native.reset()  # unseeded reset continues each plant's own stream
    o2, _ = singles.reset()
    assert np.array_equal(o1, o2)
    assert native.np_random_seed == singles.np_random_seed == (42, 43, 44, 45)


def test_vector_np_random_seed_reports_each_plants_seed():
    vec = StickSlipVectorEnv(num_envs=3)
    assert vec.np_random_seed == (None, None, None)  # no plant has a generator yet
    first, _ = vec.reset(seed=[7, None, 9])
    seeds = vec.np_random_seed
    assert seeds[0] == 7 and seeds[2] == 9 and isinstance(seeds[1], int)
    # the random seed is the one plant 1's generator was made from
    assert np.array_equal(vec.reset(seed=list(seeds))[0], first)
    vec.reset(options={"reset_mask": np.array([False, True, False])})
    assert vec.np_random_seed == seeds  # an unseeded reset keeps the plant's generator
    with pytest.raises(TypeError):
        vec.reset(seed=[1, "2", 3])
    assert vec.np_random_seed == seeds  # a refused reset reseeds nothing


def test_vector_env_with_autoreset_disabled_matches_single_envs_and_refuses_ended_plants():
    """Disabled autoreset: the caller resets ended plants (partially, by mask). Stepping
    while one is still ended is refused before any plant moves (SyncVectorEnv asserts)."""
    native, singles = _native_and_sync(3, 3, AutoresetMode.DISABLED, scene="self_excited",
                                       randomize=True)
    assert np.array_equal(native.reset(seed=5)[0], singles.reset(seed=5)[0])
    rng = np.random.default_rng(1)
    refused = 0
    for k in range(10):
        a = rng.uniform(-1, 1, native.action_space.shape)
        out = native.step(a)
        _assert_same_step(out, singles.step(a))
        ended = out[2] | out[3]
        if k == 0:  # plant 0 restarts early, so that the plants end at different steps
            ended = np.array([True, False, False])
        if ended.any():
            if k > 0:
                before = native.unwrapped._table.copy()
                with pytest.raises(gym.error.ResetNeeded, match=r"plants \[\d.*autoreset"):
                    native.step(a)
                assert np.array_equal(native.unwrapped._table, before, equal_nan=True)  # unmoved
                refused += 1
            o1, _ = native.reset(options={"reset_mask": ended})
            o2, _ = singles.reset(options={"reset_mask": ended})
            assert np.array_equal(o1, o2)
    assert refused >= 3


def test_kernel_episode_matches_python_episode():
    """The vector kernel builds an episode from its uniforms exactly as EnvSetup does."""
    from fricenv.envs import kernels
    from fricenv.envs.scenes import INITIAL, N_DRAWS, RANDOMIZABLE, new_episode_arrays
    from fricenv.envs.stick_slip import EnvSetup

    for k, name in enumerate((*RANDOMIZABLE, *INITIAL)):
        assert getattr(kernels, "D_" + name.upper()) == k  # the kernel's draw layout
    rng = np.random.default_rng(0)
    for scene in SCENES:
        for randomize in (False, True):
            setup = EnvSetup.build(scene, randomize=randomize)
            bounds = np.stack([setup.draw_lo, setup.draw_hi])
            U = rng.random((500, N_DRAWS))
            U[0], U[1] = 0.0, np.nextafter(1.0, 0.0)
            (P1, I1), (P2, I2) = new_episode_arrays(), new_episode_arrays()
            for u in U:
                setup.episode(setup.scale(u), None, P1, I1)
                kernels.episode_from_uniforms(u, bounds, setup.cfg, P2, I2)
                assert np.array_equal(P1, P2) and np.array_equal(I1, I2)


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_vector_env_matches_single_envs_across_draw_buffer_refills(mode):
    """Episodes of two steps: each plant's buffered draws run out and refill many times, in
    the kernel's autoresets and in reset() (plain, with options, reseeded), in step."""
    horizon = 2
    native, singles = _native_and_sync(3, horizon, mode, scene="self_excited", randomize=True,
                                       action_mode="both")
    rng = np.random.default_rng(0)
    for reset_kw in ({"seed": 5}, {}, {"options": {"x0": 0.5, "lam": 0.04}}, {"seed": 9}):
        assert np.array_equal(native.reset(**reset_kw)[0], singles.reset(**reset_kw)[0])
        for _ in range(DRAW_ROWS * horizon + 5):
            a = rng.uniform(-1, 1, native.action_space.shape).astype(np.float32)
            _assert_same_step(native.step(a), singles.step(a))


def test_vector_step_returns_outlive_the_next_step():
    """A step's arrays are the caller's: the next step changes none of them, and the shared
    all-True info mask cannot be written."""
    vec = StickSlipVectorEnv(num_envs=5, scene="self_excited", max_episode_steps=50)
    vec.reset(seed=3)
    rng = np.random.default_rng(1)
    first = vec.step(rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32))
    kept = [x.copy() for x in first[:4]] + [{k: v.copy() for k, v in first[4].items()}]
    for _ in range(3):
        vec.step(rng.uniform(-1, 1, vec.action_space.shape).astype(np.float32))
    for x, y in zip(first[:4], kept[:4], strict=True):
        assert np.array_equal(x, y)
    assert first[4].keys() == kept[4].keys()
    for key, value in first[4].items():
        assert np.array_equal(value, kept[4][key]), key
    mask = first[4]["_stick_fraction"]
    assert mask.all() and mask.shape == (5,)
    with pytest.raises(ValueError, match="read-only"):
        mask[0] = False


def test_vector_reset_mask_and_seed_list():
    vec = StickSlipVectorEnv(num_envs=3, autoreset_mode="Disabled")
    obs, _ = vec.reset(seed=[1, None, 3])
    single = StickSlipEnv()
    assert np.array_equal(obs[0], single.reset(seed=1)[0])
    second = single.reset()[0]
    assert np.array_equal(obs[2], StickSlipEnv().reset(seed=3)[0])
    stepped = vec.step(np.zeros((3, 1), np.float32))[0]
    obs, _ = vec.reset(options={"reset_mask": np.array([True, False, False])})
    assert np.array_equal(obs[0], second)  # plant 0 continued its own stream
    assert np.array_equal(obs[1:], stepped[1:])  # the others kept running


def test_vector_reset_mask_types_and_the_reset_after_a_failed_step():
    vec = StickSlipVectorEnv(num_envs=3, autoreset_mode="Disabled")
    with pytest.raises(gym.error.ResetNeeded, match="before calling reset"):
        vec.step(np.zeros((3, 1)))
    vec.reset(seed=0)
    for bad in (np.array([1, 0, 1]), [True, False, True], None):
        with pytest.raises(TypeError, match=r"reset_mask'\] must be a numpy bool array"):
            vec.reset(options={"reset_mask": bad})
    with pytest.raises(ValueError, match=r"reset_mask'\] must have shape \(3,\), got shape"):
        vec.reset(options={"reset_mask": np.ones(2, dtype=bool)})
    mask = np.array([False, True, False])
    vec.reset(options={"reset_mask": mask, "b3": -5.0, "v0": 3.0})  # a plant that blows up
    with pytest.raises(RuntimeError, match="plant 1"):
        for _ in range(50):
            vec.step(np.zeros((3, 1)))
    with pytest.raises(gym.error.ResetNeeded, match=r"last step failed \(plant 1\)"):
        vec.step(np.zeros((3, 1)))
    with pytest.raises(ValueError, match=r"after the failed step \(plant 1\) every plant"):
        vec.reset(options={"reset_mask": mask})
    vec.reset(seed=0)
    vec.step(np.zeros((3, 1)))
    vec.reset(options={"reset_mask": mask})  # partial resets work again


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_vector_env_copies_continue_as_the_original(how):
    """Copies and unpickled envs had views cut from the arrays the kernels write: their
    steps returned the reset observation, zero rewards and episodes that never ended."""
    import copy
    import pickle

    env = StickSlipVectorEnv(num_envs=3, scene="self_excited", max_episode_steps=4)
    env.reset(seed=0)
    env.step(np.full((3, 2), 0.3))
    clone = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    actions = np.random.default_rng(1).uniform(-1, 1, (6, 3, 2))
    truncations = rewarded = 0
    for a in actions:
        out, twin = env.step(a), clone.step(a)
        for k in range(4):
            assert np.array_equal(out[k], twin[k])
        assert out[4].keys() == twin[4].keys()
        truncations += int(twin[3].sum())
        rewarded += int((twin[1] < 0.0).sum())
    assert truncations == 3  # every plant's episode ended after its 4th step, in the copy too
    assert rewarded == 6 * 3 - 3  # all but the autoreset steps (reward 0)
    # a step where every plant reports shares one read-only mask; a copy's is read-only too
    mask = clone.step(np.zeros((3, 2)))[4]["_stick_fraction"]
    with pytest.raises(ValueError, match="read-only"):
        mask[0] = False


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_copies_of_envs_that_rendered_render_as_the_original(how):
    """A figure's artists do not survive copy.deepcopy: a copy made after a frame was drawn
    failed at its next render."""
    import copy
    import pickle

    for env in (StickSlipEnv(render_mode="rgb_array"),
                StickSlipVectorEnv(num_envs=2, render_mode="rgb_array")):
        env.reset(seed=0)
        env.render()
        clone = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
        a = np.full(env.action_space.shape, 0.5, dtype=np.float32)
        env.step(a)
        clone.step(a)
        assert np.array_equal(np.asarray(env.render()), np.asarray(clone.render()))
        env.close()
        clone.close()


def test_sb3_adapter_checks_indices_and_sets_shared_attributes_for_all_plants():
    """The plants share one vector env: an attribute set for some of them would change them
    all (it did), and an index past the plants answered as if it were one."""
    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    venv = StickSlipSB3VecEnv(num_envs=3, max_episode_steps=100)
    assert venv.get_attr("max_episode_steps", indices=[0, -1]) == [100, 100]
    assert venv.env_method("snapshot", 0, indices=2)[0]["V"] == venv.venv.snapshot(0)["V"]
    calls = (lambda bad: venv.get_attr("max_episode_steps", indices=bad),
             lambda bad: venv.env_method("snapshot", 0, indices=bad),
             lambda bad: venv.env_is_wrapped(gym.wrappers.TimeLimit, indices=bad))
    for bad in ([3], 5, [-4]):
        for call in calls:
            with pytest.raises(IndexError, match=f"index {np.ravel(bad)[0]} is out of range"):
                call(bad)
    with pytest.raises(TypeError, match="indices must be ints"):
        venv.get_attr("max_episode_steps", indices=[0.5])
    for mode in (AutoresetMode.NEXT_STEP, "Disabled"):
        with pytest.raises(ValueError, match="SB3 needs same-step autoreset"):
            StickSlipSB3VecEnv(num_envs=1, autoreset_mode=mode)
    assert StickSlipSB3VecEnv(num_envs=1, autoreset_mode="SameStep").num_envs == 1
    with pytest.raises(ValueError, match="only be set for all of them"):
        venv.set_attr("max_episode_steps", 3, indices=[0])
    assert venv.get_attr("max_episode_steps") == [100, 100, 100]  # nothing changed
    venv.set_attr("max_episode_steps", 7, indices=[2, 0, 1])  # all plants: allowed
    assert venv.venv.max_episode_steps == 7


def test_sb3_adapter_reports_each_episodes_stick_fraction_when_it_ends(tmp_path):
    """VecMonitor logged the info's stick_fraction at an episode's end: the last interval's
    (0 or 1 mostly), not the episode's."""
    import csv

    from stable_baselines3.common.vec_env import VecMonitor

    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    path = tmp_path / "monitor.csv"
    venv = VecMonitor(StickSlipSB3VecEnv(num_envs=2, max_episode_steps=7), str(path),
                      info_keywords=("episode_stick_fraction",))
    venv.seed(3)
    venv.reset()
    actions = np.random.default_rng(0).uniform(-1, 1, (30, 2, 1)).astype(np.float32)
    running, ended = np.zeros(2), []
    for a in actions:
        _, _, dones, infos = venv.step(a)
        running += [info["stick_fraction"] for info in infos]
        for i in np.flatnonzero(dones):
            assert infos[i]["episode_stick_fraction"] == pytest.approx(running[i] / 7, 1e-12)
            ended.append(running[i] / 7)
            running[i] = 0.0
    venv.close()
    rows = list(csv.DictReader(path.read_text().splitlines()[1:]))
    assert len(rows) == len(ended) == 8 and len({round(x, 3) for x in ended}) > 2
    assert [float(r["episode_stick_fraction"]) for r in rows] == pytest.approx(ended, abs=1e-6)


def test_vector_max_episode_steps_can_be_changed_and_autoreset_mode_cannot():
    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    venv = StickSlipSB3VecEnv(num_envs=2, max_episode_steps=100)
    venv.set_attr("max_episode_steps", 3)
    assert venv.get_attr("max_episode_steps") == [3, 3]
    venv.seed(0)
    venv.reset()
    dones = [venv.step(np.zeros((2, 1), np.float32))[2].tolist() for _ in range(4)]
    assert dones == [[False, False], [False, False], [True, True], [False, False]]
    vec = StickSlipVectorEnv(num_envs=2, max_episode_steps=100)
    for bad, err in ((0, ValueError), (2.5, TypeError), (True, TypeError), (2**63, ValueError)):
        with pytest.raises(err, match="max_episode_steps"):
            vec.max_episode_steps = bad
    with pytest.raises(ValueError, match="max_episode_steps must be an integer <= "):
        StickSlipVectorEnv(num_envs=1, max_episode_steps=2**63)  # (it overflowed the counter)
    assert vec.max_episode_steps == 100
    with pytest.raises(AttributeError):
        vec.autoreset_mode = AutoresetMode.SAME_STEP
    assert venv.env_is_wrapped(gym.wrappers.TimeLimit) == [True, True]
    assert venv.env_is_wrapped(gym.wrappers.ClipAction) == [False, False]


def test_control_dt_below_the_time_resolution_is_refused():
    with pytest.raises(ValueError, match=r"control_dt is out of range \(at least 1e-06\)"):
        gym.make(ENV_ID, control_dt=1e-300)
    gym.make(ENV_ID, control_dt=1e-6).reset(seed=0)


# -- rendering ------------------------------------------------------------------------------
def test_starts_far_out_are_bounded_like_parameters():
    """A start at x0 = 1e200 overflowed the reward to NaN; one at 1e12 (the bound) is
    accepted, rewards stay in range, and a frame of the block that far out is cheap (a belt
    mark per unit was a 7 TiB array)."""
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)  # (Gymnasium's env checker breaks if the very first reset is refused)
    for key in ("x0", "v0"):
        with pytest.raises(ValueError, match=rf"reset option '{key}' must lie within"):
            env.reset(seed=0, options={key: -1e200})
    with pytest.raises(ValueError, match=r"x0 must lie within"):
        fricenv.OscillatorState.start(fricenv.OscillatorParams(), 1e13)
    env.reset(seed=0, options={"x0": 1e12, "v0": -1e12})
    reward, terminated = env.step(env.action_space.sample())[1:3]
    assert -1.6 <= reward <= 0.0 and terminated  # far outside the observation box
    frame = env.render()
    assert frame.ndim == 3 and frame.std() > 0
    env.close()


def test_params_given_at_make_are_not_randomised():
    env = gym.make(ENV_ID, randomize=True, params={"lam": 0.2, "V": 3.0}).unwrapped
    for seed in range(4):
        env.reset(seed=seed)
        assert env.snapshot()["V"] == 3.0
        assert env._P[fricenv.params.P_LAM] == 0.2
        assert env._P[fricenv.params.P_XFK] != 2.5  # the others are still drawn
    vec = gym.make_vec(ENV_ID, num_envs=3, randomize=True, params={"lam": 0.2})
    vec.reset(seed=0)
    assert np.all(vec.unwrapped._P[:, fricenv.params.P_LAM] == 0.2)


def test_sampled_stuck_flag_is_the_mode_at_that_instant():
    env = gym.make(SELF_ID).unwrapped
    env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(150):
        a = rng.uniform(-1, 1, 2).astype(np.float32)
        stuck = env.sample_interval(a, 1)[2]
        obs = env.step(a)[0]
        assert stuck[-1] == bool(obs[2])


def test_render_rgb_array_single_and_vector():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 0
    env.close()
    vec = gym.make_vec(ENV_ID, num_envs=2, render_mode="rgb_array")
    vec.reset(seed=0)
    vec.step(np.zeros((2, 1), np.float32))
    frames = vec.render()
    assert len(frames) == 2 and frames[0].shape == frame.shape
    vec.close()


def test_vector_render_traces_ignore_a_rejected_step():
    vec = StickSlipVectorEnv(num_envs=2, render_mode="rgb_array")
    vec.reset(seed=0)
    traces = [tr.t[: tr.n].copy() for tr in vec._traces]
    a = np.zeros((2, 1), np.float32)
    a[1, 0] = np.nan  # plant 0's action is fine, but the step is refused as a whole
    with pytest.raises(ValueError, match="action 1"):
        vec.step(a)
    assert all(np.array_equal(tr.t[: tr.n], t) for tr, t in zip(vec._traces, traces, strict=True))
    vec.close()


def test_render_without_render_mode_warns_and_returns_none():
    # StickSlipEnv() has no spec: this used to fail on `assert self.spec is not None`
    for env in (StickSlipEnv(), gym.make(ENV_ID).unwrapped, StickSlipVectorEnv(num_envs=2)):
        with pytest.warns(UserWarning, match=r"without specifying any render mode.*render_mode="):
            assert env.render() is None


def test_no_render_mode_prepares_nothing():
    code = (
        "import sys, numpy as np, gymnasium as gym\n"
        "from fricenv.envs import register_envs\n"
        "register_envs()\n"
        "had_mpl = 'matplotlib' in sys.modules\n"
        f"env = gym.make('{ENV_ID}')\n"
        "env.reset(seed=0); env.step(np.zeros(1, np.float32)); env.close()\n"
        "assert env.unwrapped._renderer is None\n"
        "assert 'fricenv.envs.rendering' not in sys.modules\n"
        "assert had_mpl or 'matplotlib' not in sys.modules, 'the env imported matplotlib'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


# -- stable-baselines3 ----------------------------------------------------------------------
def test_sb3_adapter_matches_dummy_vec_env():
    from stable_baselines3.common.vec_env import DummyVecEnv

    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    n = 3
    ours = StickSlipSB3VecEnv(num_envs=n, max_episode_steps=6, action_mode="both")
    ref = DummyVecEnv([lambda: gym.make(ENV_ID, max_episode_steps=6, action_mode="both")] * n)
    ours.seed(7)
    ref.seed(7)
    assert np.array_equal(ours.reset(), ref.reset())
    rng = np.random.default_rng(0)
    for _ in range(14):
        a = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        o1, r1, d1, i1 = ours.step(a)
        o2, r2, d2, i2 = ref.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        for x, y in zip(i1, i2, strict=True):
            assert x["stick_fraction"] == y["stick_fraction"]
            assert ("terminal_observation" in x) == ("terminal_observation" in y)
            if "terminal_observation" in x:
                assert np.array_equal(x["terminal_observation"], y["terminal_observation"])
                assert x["TimeLimit.truncated"] == y["TimeLimit.truncated"]
    assert ours.get_attr("render_mode") == [None] * n


def test_ppo_smoke_single_env():
    from stable_baselines3 import PPO

    env = gym.make(ENV_ID, action_mode="both")
    model = PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(256)
    action, _ = model.predict(env.reset(seed=0)[0], deterministic=True)
    assert env.action_space.contains(action)


def test_ppo_smoke_vector_env():
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor

    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    venv = VecMonitor(StickSlipSB3VecEnv(num_envs=8, scene="self_excited", max_episode_steps=20))
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(512)
    assert model.num_timesteps >= 512
    assert len(model.ep_info_buffer) > 0  # episodes ended and were reported


@pytest.mark.slow
def test_ppo_learns_to_quench_self_excited_stick_slip():
    """Under a minute of PPO (200k steps, 64 plants) far outdoes doing nothing."""
    from stable_baselines3 import PPO

    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    venv = StickSlipSB3VecEnv(num_envs=64, scene="self_excited", max_episode_steps=200)
    model = PPO("MlpPolicy", venv, n_steps=64, batch_size=1024, seed=0, device="cpu")
    model.learn(200_000)
    env = gym.make(SELF_ID, max_episode_steps=200)

    def episode_return(policy):
        obs, _ = env.reset(seed=123)
        total, done = 0.0, False
        while not done:
            obs, r, term, trunc, _ = env.step(policy(obs))
            total += r
            done = term or trunc
        return total

    idle = episode_return(lambda obs: np.array([-1.0, 0.0], np.float32))
    learned = episode_return(lambda obs: model.predict(obs, deterministic=True)[0])
    assert learned > idle + 40.0  # measured: about -3 against -82 idle (200 steps)


def _parallel_and_serial(n, **kw):
    """Two vector envs alike but for their kernel: (parallel, serial)."""

    kw = {"scene": "self_excited", "randomize": True, "max_episode_steps": 9, **kw}
    par = gym.make_vec(ENV_ID, num_envs=n, **kw)
    ser = gym.make_vec(ENV_ID, num_envs=n, **kw)
    par._step_kernel = par._steppers.step_batch_parallel
    ser._step_kernel = ser._steppers.step_batch
    par._watch_workers = lambda: None  # compare the kernels: no serial spells
    return par, ser


def _run_both(par, ser, steps=20):
    assert np.array_equal(par.reset(seed=3)[0], ser.reset(seed=3)[0])
    rng = np.random.default_rng(1)
    for _ in range(steps):
        a = rng.uniform(-1, 1, par.action_space.shape).astype(np.float32)
        _assert_same_step(par.step(a), ser.step(a))


@pytest.mark.parametrize(
    ("n", "n_workers", "pairs"),
    [(77, 1, 1), (77, 2, 1), (77, 5, 3), (3, 8, 4), (77, 4, 0)],
    ids=["1-worker", "2-workers", "5-workers", "3-plants-8-workers", "no-counter-slots"],
)
def test_parallel_batch_kernel_matches_serial(n, n_workers, pairs):
    """Plants shared out over workers give bit-identical results to the serial kernel.

    Every plant must be stepped exactly once whatever the worker count (pairs meet inside
    their region, an odd one out has a region alone), however the plants fall into chunks
    (77 leave partial chunks; 3 plants leave most regions empty), and without counter slots
    in ``ivars`` (the kernel then steps the plants in order).
    """
    from fricenv.envs import kernels

    par, ser = _parallel_and_serial(n)
    ivars = np.zeros(kernels.N_IVARS + pairs * kernels.COUNTER_STRIDE, dtype=np.int64)
    ivars[: kernels.N_IVARS] = par._ivars[: kernels.N_IVARS]
    ivars[kernels.IV_N_WORKERS] = n_workers
    par._ivars = ivars
    _run_both(par, ser)


def test_parallel_batch_kernel_after_thread_count_changes():
    """The env's own workers stay correct when numba's thread count changes after it is
    built (fewer threads run some workers in turn)."""
    from fricenv.envs import vector as vec_mod

    before = numba.get_num_threads()
    par, ser = _parallel_and_serial(vec_mod.PARALLEL_MIN_ENVS)
    try:
        numba.set_num_threads(1)
        _run_both(par, ser, steps=5)
    finally:
        numba.set_num_threads(before)
    _run_both(par, ser, steps=5)


def test_late_workers_send_the_vector_env_serial_for_doubling_stretches(monkeypatch):
    """Workers that keep finding their region done (here: two workers run in turn on one
    thread, as on a machine busy with other processes) make the env step serially, in
    stretches that double while the PROBE_STEPS parallel steps between them all find a late
    worker again; one step with every worker on time ends the spell. The results never
    change."""
    from fricenv.envs import kernels
    from fricenv.envs import vector as vec_mod

    par, ser = _parallel_and_serial(vec_mod.PARALLEL_MIN_ENVS)  # 6 cells for 2 workers
    del par._watch_workers  # the env's own policy, under test here
    par._ivars = np.zeros(kernels.N_IVARS + kernels.COUNTER_STRIDE, dtype=np.int64)
    par._ivars[: kernels.N_IVARS] = ser._ivars[: kernels.N_IVARS]
    par._ivars[kernels.IV_N_WORKERS] = 2
    late, first, probe = vec_mod.LATE_STEPS, vec_mod.SERIAL_STRETCH_MIN, vec_mod.PROBE_STEPS
    n_steps = late + first + probe + 2 * first + probe
    serial_steps = []
    step_batch = par._serial_kernel

    def counted(*args):
        serial_steps.append(k)
        return step_batch(*args)

    monkeypatch.setattr(par, "_serial_kernel", counted)
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        assert np.array_equal(par.reset(seed=3)[0], ser.reset(seed=3)[0])
        rng = np.random.default_rng(1)
        for k in range(n_steps):
            a = rng.uniform(-1, 1, par.action_space.shape).astype(np.float32)
            _assert_same_step(par.step(a), ser.step(a))
            if k < late:
                assert par._ivars[kernels.IV_N_LATE] == 1
    finally:
        numba.set_num_threads(before)
    parallel_steps = sorted(set(range(n_steps)) - set(serial_steps))
    second_probe = late + first + probe + 2 * first
    assert parallel_steps == [*range(late), *range(late + first, late + first + probe),
                              *range(second_probe, second_probe + probe)]
    assert par._serial_left == 4 * first
    par._ivars[kernels.IV_N_LATE] = 0  # as after a parallel step with every worker on time
    par._watch_workers()
    assert par._late_steps == 0 and par._serial_stretch == first


@pytest.mark.parametrize("size", [0, 1, 7, 8, 9, 16, 17, 23, 40, 64, 77, 128, 256, 1000])
def test_cells_of_a_region_cover_it_once_for_any_meeting_point(size):
    """Whatever share of a region's claims the front worker wins, its cells and the back
    worker's tile the region exactly; a region of a few chunks or more opens with two big
    cells, one for each worker's first claim, of at most a third of it each, and keeps at
    least two chunks between them."""
    from fricenv.envs import batch

    lo, hi = 5, 5 + size
    big, n_cells = batch._cells(lo, hi)
    if size >= 4 * batch.CHUNK:
        assert big > 0 and n_cells >= 4
        assert size - 2 * big >= 2 * batch.CHUNK
    # a worker slowed to half its partner's speed can still end with its balanced third
    assert 3 * big <= size
    for a in range(n_cells + 1):
        hits = np.zeros(hi, dtype=np.int64)
        for done in range(a):
            start, end = batch._cell(lo, hi, big, n_cells, done, False)
            assert start < end
            hits[start:end] += 1
        for done in range(n_cells - a):
            start, end = batch._cell(lo, hi, big, n_cells, done, True)
            assert start < end
            hits[start:end] += 1
        assert np.all(hits[lo:hi] == 1) and np.all(hits[:lo] == 0)


@pytest.mark.parametrize("n_workers", [1, 2, 3, 5, 8])
def test_regions_tile_the_plants(n_workers):
    from fricenv.envs import batch

    for n in (0, 1, 3, 64, 77, 256):
        hits = np.zeros(n, dtype=np.int64)
        for first in range(0, n_workers, 2):
            lo, hi = batch._region(first, n_workers, n)
            assert batch._region(min(first + 1, n_workers - 1), n_workers, n) == (lo, hi)
            hits[lo:hi] += 1
        assert np.all(hits == 1)


def test_every_kernel_status_has_its_own_message() -> None:
    """A plant too stiff for the integrator says so (not "failed with status 4")."""
    from fricenv.envs.stick_slip import raise_status
    from fricenv.layout import STATUS_EVENT_CAP, STATUS_NONFINITE, STATUS_TOO_STIFF

    for status, text in ((STATUS_EVENT_CAP, "chattered"), (STATUS_NONFINITE, "NaN"),
                         (STATUS_TOO_STIFF, "too stiff")):
        with pytest.raises(RuntimeError, match=text):
            raise_status(status, None, " 3")


@pytest.mark.parametrize("mode", [5, [], b"rgb_array"])
def test_a_render_mode_that_is_no_str_is_named_by_every_env(mode) -> None:
    """gym.make(..., render_mode=5) raised AttributeError from inside gymnasium (it calls
    render_mode.endswith on a mode not among the env's)."""
    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    match = r"render_mode must be one of \[.*'rgb_array'\] or None, got"
    makers = [lambda: gym.make("fricenv/StickSlip-v0", render_mode=mode),
              lambda: gym.make_vec("fricenv/StickSlip-v0", num_envs=2, render_mode=mode,
                                   vectorization_mode="vector_entry_point"),
              lambda: StickSlipEnv(render_mode=mode),
              lambda: StickSlipVectorEnv(num_envs=2, render_mode=mode),
              lambda: StickSlipSB3VecEnv(num_envs=2, render_mode=mode)]
    for make in makers:
        with pytest.raises(TypeError, match=match):
            make()
    with pytest.raises(ValueError, match=r"render_mode must be one of \['human', 'rgb_array'\]"):
        StickSlipEnv(render_mode="ascii")
    assert "rgb_array" in StickSlipEnv.metadata["render_modes"]
    assert None not in StickSlipEnv.metadata["render_modes"]
