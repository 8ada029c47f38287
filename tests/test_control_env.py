"""Control studies' environment features: the Stribeck and viscous scenes, sensor and
actuator options, the plant-state API and the batch rollout."""

from __future__ import annotations

import copy
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import fricenv  # noqa: F401  (registers the environments)
from fricenv.envs import ENV_IDS
from fricenv.envs import kernels as K
from fricenv.envs.rollout import STATUS_LEFT_BOX, BatchRollout, rollout_batch
from fricenv.envs.scenes import SCENES
from fricenv.envs.sensors import CHANNELS, NOISE_ROWS, Instruments
from fricenv.envs.state import N_PLANT, PL_WORK, PlantState
from fricenv.envs.stick_slip import StickSlipEnv
from fricenv.envs.vector import StickSlipVectorEnv

NEW_IDS = {"stribeck": "fricenv/StickSlipStribeck-v0", "viscous": "fricenv/StickSlipViscous-v0"}
#: Every sensor and actuator option on at once.
ALL_OPTIONS = {"obs_noise": {"x": 0.05, "v_rel": 0.1, "cos1": 0.02}, "obs_delay": 2,
               "observe": ("x", "phases", "settings"), "actuator_lag": 1.0,
               "actuator_rate": 0.2}
#: ... with each episode's noise scale and delay drawn too.
RANDOM_SENSORS = {**ALL_OPTIONS, "randomize_sensors": True}


def _actions(env, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (n, *env.action_space.shape)).astype(np.float32)


def _no_warnings(fn, *args, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn(*args, **kwargs)
    caught = [w for w in caught if not str(w.message).startswith("render_mode='human'")]
    assert not caught, [str(w.message) for w in caught]


# -- scenes ---------------------------------------------------------------------------------
@pytest.mark.parametrize("scene", sorted(NEW_IDS))
def test_new_scenes_are_registered_and_pass_both_checkers(scene):
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env_id = NEW_IDS[scene]
    assert ENV_IDS[env_id] == scene
    spec = gym.spec(env_id)
    assert spec.max_episode_steps == SCENES[scene].max_episode_steps
    assert f"`{scene}` (`{env_id}`)" in StickSlipEnv.__doc__  # in the docstring's scene list
    _no_warnings(check_env, gym.make(env_id, randomize=True).unwrapped)
    _no_warnings(sb3_check_env, gym.make(env_id), warn=True)
    env = gym.make(env_id)
    env.reset(seed=0)
    assert env.unwrapped.params["b1"] == 0.2 and env.action_space.shape == (2,)


@pytest.mark.parametrize("scene", sorted(NEW_IDS))
def test_new_scenes_stick_slip_unforced_and_some_excitation_quenches(scene):
    """Self-excited: the block sticks a lot with the excitation off; u0 = 3.5 on both tones
    in phase (nu = 1) cuts it by more than half within the episode's horizon."""
    sc = SCENES[scene]

    def stick(u0):
        vec = StickSlipVectorEnv(num_envs=4, scene=scene)
        vec.reset(seed=3)
        a_u = 2.0 * (u0 - sc.u0_range[0]) / (sc.u0_range[1] - sc.u0_range[0]) - 1.0
        a = np.tile(np.array([a_u, 0.0], np.float32), (4, 1))  # nu = 1: mid-range
        fr = [vec.step(a)[4]["stick_fraction"] for _ in range(sc.max_episode_steps)]
        return float(np.mean(fr[100:]))

    unforced = stick(0.0)
    assert unforced > 0.3
    assert stick(3.5) < 0.5 * unforced


@pytest.mark.parametrize("scene", sorted(NEW_IDS))
def test_new_scenes_vector_env_and_sb3_adapter_match_single_envs(scene):
    from stable_baselines3.common.vec_env import DummyVecEnv

    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    env_id = NEW_IDS[scene]
    n = 3
    vec = gym.make_vec(env_id, num_envs=n, max_episode_steps=9, randomize=True)
    ref = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync", max_episode_steps=9,
                       randomize=True)
    assert np.array_equal(vec.reset(seed=4)[0], ref.reset(seed=4)[0])
    for a in _actions(vec, 20):
        o1, r1, t1, u1, _ = vec.step(a)
        o2, r2, t2, u2, _ = ref.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(u1, u2)
    ours = StickSlipSB3VecEnv(num_envs=n, scene=scene, max_episode_steps=6)
    dummy = DummyVecEnv([lambda: gym.make(env_id, max_episode_steps=6)] * n)
    ours.seed(7)
    dummy.seed(7)
    assert np.array_equal(ours.reset(), dummy.reset())
    for a in _actions(vec, 14, seed=1):
        s1, s2 = ours.step(a), dummy.step(a)
        for x, y in zip(s1[:3], s2[:3], strict=True):
            assert np.array_equal(x, y)


# -- sensors and actuators ------------------------------------------------------------------
def test_options_off_change_nothing():
    plain = StickSlipEnv(scene="self_excited")
    off = StickSlipEnv(scene="self_excited", obs_noise=0.0, obs_delay=0, observe=CHANNELS,
                       actuator_lag=0.0, actuator_rate=None)
    assert off.setup.instruments is None
    assert np.array_equal(plain.reset(seed=1)[0], off.reset(seed=1)[0])
    for a in _actions(plain, 30):
        assert np.array_equal(plain.step(a)[0], off.step(a)[0])


def test_noise_has_the_given_standard_deviation_per_channel_and_seeds_replay():
    std = {"x": 0.05, "v_rel": 0.2, "u0": 0.01}
    noisy = StickSlipEnv(scene="self_excited", obs_noise=std)
    exact = StickSlipEnv(scene="self_excited")
    noisy.reset(seed=0)
    exact.reset(seed=0)
    diffs = []
    for a in _actions(exact, 3000):
        o1 = noisy.step(a)[0]
        o2 = exact.step(a)[0]
        diffs.append(o1.astype(np.float64) - o2)
    d = np.array(diffs)
    for k, name in enumerate(CHANNELS):
        want = std.get(name, 0.0)
        if name == "u0":  # clipped at u0 = 0 (the box's edge) when the excitation is off
            continue
        assert abs(d[:, k].std() - want) < 0.05 * want + 1e-12, name
        assert abs(d[:, k].mean()) < 4 * want / np.sqrt(len(d)) + 1e-12, name
    # the same seed replays the same noise; the episodes' draws are a noise-free env's
    again = StickSlipEnv(scene="self_excited", obs_noise=std)
    noisy.reset(seed=5)
    again.reset(seed=5)
    exact.reset(seed=5)
    plant_end = N_PLANT - (K.N_TABLE - K.T_WORK)  # (the parts before the workspace)
    assert np.array_equal(noisy.get_state().plant[:plant_end], exact.get_state().plant[:plant_end])
    acts = _actions(exact, 50, seed=2)
    assert all(np.array_equal(noisy.step(a)[0], again.step(a)[0]) for a in acts)
    assert np.all(noisy.observation_space.contains(noisy.reset(seed=6)[0]))


def test_delay_returns_the_observation_k_steps_earlier_and_partial_observation_picks():
    k = 3
    exact = StickSlipEnv(scene="stribeck")
    late = StickSlipEnv(scene="stribeck", obs_delay=k, observe=("x", "phases"))
    assert late.observation_space.shape == (5,)
    picked = [CHANNELS.index(c) for c in ("x", "cos1", "sin1", "cos2", "sin2")]
    history = [exact.reset(seed=2)[0]]
    first = late.reset(seed=2)[0]
    assert np.array_equal(first, history[0][picked])
    for t, a in enumerate(_actions(exact, 40)):
        history.append(exact.step(a)[0])
        got = late.step(a)[0]
        assert np.array_equal(got, history[max(0, t + 1 - k)][picked])
        assert late.observation_space.contains(got)


def test_actuator_rate_limit_and_lag():
    rate = 0.05
    env = StickSlipEnv(scene="self_excited", actuator_rate=rate)
    obs, _ = env.reset(seed=0)
    (ulo, uhi), (nlo, nhi) = env.scene.u0_range, env.scene.nu_range
    prev = obs
    for a in [np.array([1.0, 1.0], np.float32)] * 5 + [np.array([-1.0, -1.0], np.float32)] * 3:
        obs = env.step(a)[0]
        assert abs(obs[K.O_U0] - prev[K.O_U0]) <= rate * (uhi - ulo) + 1e-6
        assert abs(obs[K.O_NU] - prev[K.O_NU]) <= rate * (nhi - nlo) + 1e-6
        prev = obs
    assert obs[K.O_U0] == pytest.approx(2 * rate * (uhi - ulo), abs=1e-6)  # 5 up, 3 down
    lag = 2.0
    env = StickSlipEnv(scene="self_excited", actuator_lag=lag)
    env.reset(seed=0)
    u = [env.step(np.array([1.0, 0.0], np.float32))[0][K.O_U0] for _ in range(6)]
    frac = 1.0 - np.exp(-env.dt * np.arange(1, 7) / lag)  # first order towards u0 = 2
    np.testing.assert_allclose(u, uhi * frac, rtol=1e-6)
    # sample_interval previews what the actuator would apply and leaves it untouched
    before = env.get_state()
    t, v, _ = env.sample_interval(np.array([-1.0, 1.0], np.float32), 4)
    assert env.get_state().same_as(before)
    o = env.step(np.array([-1.0, 1.0], np.float32))[0]
    assert v[-1] == pytest.approx(o[K.O_VR], abs=1e-6)


@pytest.mark.parametrize("options", [ALL_OPTIONS, RANDOM_SENSORS], ids=["fixed", "drawn"])
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_vector_env_matches_single_envs_with_every_option_on(mode, options):
    kw = {"scene": "self_excited", "randomize": True, **options}
    env_id = "fricenv/StickSlipSelfExcited-v0"
    native = gym.make_vec(env_id, num_envs=3, max_episode_steps=7, autoreset_mode=mode, **kw)
    singles = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync", max_episode_steps=7,
                           vector_kwargs={"autoreset_mode": mode}, **kw)
    assert native.single_observation_space == singles.single_observation_space
    assert np.array_equal(native.reset(seed=8)[0], singles.reset(seed=8)[0])
    for a in _actions(native, NOISE_ROWS + 10):  # noise buffers refill on the way
        o1, r1, t1, u1, i1 = native.step(a)
        o2, r2, t2, u2, i2 = singles.step(a)
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2)
        assert np.array_equal(t1, t2) and np.array_equal(u1, u2)
        for x, y in zip(i1.get("final_obs", ()), i2.get("final_obs", ()), strict=True):
            assert (x is None and y is None) or np.array_equal(x, y)
    assert np.array_equal(native.reset()[0], singles.reset()[0])
    # the sensors' reset options, then autoresets drawing again
    sensor_options = {"obs_noise_scale": 0.5, "obs_delay": 1}
    assert np.array_equal(native.reset(options=sensor_options)[0],
                          singles.reset(options=sensor_options)[0])
    for a in _actions(native, 12, seed=4):
        assert np.array_equal(native.step(a)[0], singles.step(a)[0])


def test_both_checkers_pass_with_every_option_on():
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(NEW_IDS["stribeck"], randomize=True, **ALL_OPTIONS)
    _no_warnings(check_env, env.unwrapped)
    _no_warnings(sb3_check_env, gym.make(NEW_IDS["viscous"], **ALL_OPTIONS), warn=True)


def test_vector_env_with_options_and_disabled_autoreset_matches_single_envs():
    kw = {"scene": "paper", **ALL_OPTIONS}
    native = StickSlipVectorEnv(num_envs=2, max_episode_steps=3,
                                autoreset_mode=AutoresetMode.DISABLED, **kw)
    singles = [gym.wrappers.TimeLimit(StickSlipEnv(**kw), 3) for _ in range(2)]
    assert np.array_equal(native.reset(seed=3)[0],
                          np.stack([e.reset(seed=3 + i)[0] for i, e in enumerate(singles)]))
    for a in _actions(native, 9):
        o, _, term, trunc, _ = native.step(a)
        ref = [e.step(a[i]) for i, e in enumerate(singles)]
        assert np.array_equal(o, np.stack([r[0] for r in ref]))
        ended = term | trunc
        if ended.any():
            o, _ = native.reset(options={"reset_mask": ended})
            for i in np.flatnonzero(ended):
                assert np.array_equal(o[i], singles[i].reset()[0])


def test_bad_sensor_and_actuator_options_are_named():
    for kw, err, match in (
        ({"obs_noise": -0.1}, ValueError, "obs_noise"),
        ({"obs_noise": {"speed": 0.1}}, ValueError, "unknown channel 'speed'"),
        ({"obs_noise": [0.1] * 3}, ValueError, "nine"),
        ({"obs_noise": "loud"}, TypeError, "obs_noise"),
        ({"obs_delay": 1.5}, TypeError, "obs_delay"),
        ({"obs_delay": -1}, ValueError, "obs_delay"),
        ({"observe": ("x", "x")}, ValueError, "twice"),
        ({"observe": ("speed",)}, ValueError, "unknown channel 'speed'"),
        ({"observe": ()}, ValueError, "at least one"),
        ({"actuator_lag": -1.0}, ValueError, "actuator_lag"),
        ({"actuator_rate": 0.0}, ValueError, "actuator_rate"),
        ({"actuator_rate": "fast"}, TypeError, "actuator_rate"),
    ):
        with pytest.raises(err, match=match):
            StickSlipEnv(**kw)
    assert Instruments.build(observe="phases").channels == (3, 4, 5, 6)


# -- plant state ----------------------------------------------------------------------------
@pytest.mark.parametrize("kw", [{"scene": "paper"}, {"scene": "stribeck", "randomize": True},
                                {"scene": "viscous", **ALL_OPTIONS},
                                {"scene": "viscous", **RANDOM_SENSORS}])
def test_state_round_trip_replays_bit_for_bit(kw):
    env = StickSlipEnv(**kw)
    env.reset(seed=11)
    for a in _actions(env, 13):
        last = env.step(a)[0]
    state = env.get_state()
    assert state.plant.shape == (N_PLANT,) and state.episode_steps == 13
    assert state.params["lam"] == env.params["lam"] and state.u0 == env.params["u0"]
    acts = _actions(env, 25, seed=3)
    first = [env.step(a) for a in acts]
    after = env.get_state()
    assert np.array_equal(env.set_state(state), last)  # the observation it was saved with
    again = [env.step(a) for a in acts]
    for (o1, r1, t1, _, i1), (o2, r2, t2, _, i2) in zip(first, again, strict=True):
        assert np.array_equal(o1, o2) and r1 == r2 and t1 == t2 and i1 == i2
    assert env.get_state().same_as(after)
    # the state is a copy: stepping on leaves it as it was, and it restores into a copy of
    # the env, into a vector env's plant, and survives pickling
    other = copy.deepcopy(env)
    other.set_state(pickle.loads(pickle.dumps(state)))
    assert all(np.array_equal(other.step(a)[0], f[0]) for a, f in zip(acts, first, strict=True))
    vec = StickSlipVectorEnv(num_envs=2, **kw)
    vec.reset(seed=0)
    vec.set_state(1, state)
    for a, f in zip(acts, first, strict=True):
        o = vec.step(np.stack([a, a]))[0]
        assert np.array_equal(o[1], f[0])
    assert vec.get_state(1).plant.tobytes() == env.get_state().plant.tobytes()


def test_set_state_refuses_what_does_not_fit():
    env = StickSlipEnv(scene="paper")
    with pytest.raises(gym.error.ResetNeeded):
        env.get_state()
    env.reset(seed=0)
    state = env.get_state()
    with pytest.raises(TypeError, match="PlantState"):
        env.set_state({"x": 1.0})
    bad = PlantState(state.plant[:-1], state.command)
    with pytest.raises(ValueError, match="plant"):
        env.set_state(bad)
    plant = state.plant.copy()
    plant[0] = -1.0  # lam < 0
    with pytest.raises(ValueError, match="lam"):
        env.set_state(PlantState(plant, state.command))
    with pytest.raises(ValueError, match="same options"):
        StickSlipEnv(scene="paper", obs_delay=1).set_state(state)
    vec = StickSlipVectorEnv(num_envs=2)
    with pytest.raises(gym.error.ResetNeeded):
        vec.get_state(0)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match="plant index"):
        vec.get_state(2)


@pytest.mark.parametrize("vector", [False, True])
def test_set_state_refuses_a_nan_delay_line_or_noise_stream(vector):
    """A NaN reading in the delay line or a NaN unread normal was restored, and reached
    the agent's observation steps later."""
    from dataclasses import replace

    kw = {"scene": "viscous", **ALL_OPTIONS}
    env = StickSlipVectorEnv(num_envs=2, **kw) if vector else StickSlipEnv(**kw)
    env.reset(seed=0)
    state = env.get_state(0) if vector else env.get_state()
    put = (lambda s: env.set_state(1, s)) if vector else env.set_state
    assert state.delay is not None and state.noise is not None
    delay = state.delay.copy()
    delay[-1, 2] = np.nan
    with pytest.raises(ValueError, match=r"state\.delay holds a non-finite reading "
                                         r"\(nan at row \d+, column 2\)"):
        put(replace(state, delay=delay))
    gen, rows = state.noise
    rows = np.vstack([rows, np.zeros((1, rows.shape[1]))]) if rows.shape[0] == 0 else rows.copy()
    rows[0, 4] = np.inf
    with pytest.raises(ValueError, match=r"state\.noise: unread normals hold a non-finite "
                                         r"value \(inf at row 0, column 4\)"):
        put(replace(state, noise=(gen, rows)))
    put(state)  # the env is unharmed and takes the state as it was
    after = env.get_state(1) if vector else env.get_state()
    assert np.array_equal(after.delay, state.delay)


@pytest.mark.parametrize("vector", [False, True])
def test_set_state_refuses_what_run_stats_refuses(vector):
    """A state is held to run_stats' own check: a stuck plant off the belt speed (it stepped
    as stuck while reporting v - V = 4), magnitudes beyond 1e12 (v = 1e300, xfs = 1e300,
    t = 1e17, where time stood still) were restored and stepped."""
    from fricenv.envs.state import PL_P, PL_S
    from fricenv.layout import S_MODE, S_T, S_V, S_X
    from fricenv.params import P_XFS

    env = StickSlipVectorEnv(num_envs=2) if vector else StickSlipEnv(scene="paper")
    env.reset(seed=0)
    state = env.get_state(0) if vector else env.get_state()
    put = (lambda s: env.set_state(1, s)) if vector else env.set_state
    stuck = state.plant.copy()
    stuck[PL_S + S_MODE], stuck[PL_S + S_V] = 0.0, 5.0  # the belt runs at V = 1
    cases = [(stuck, r"state\.mode = 0 \(stick\) needs v == V = 1\.0, got state\.v = 5\.0")]
    for slot, value, match in ((S_V, 1e300, r"state\.v must lie within \+-1e\+12, .*1e\+300"),
                               (S_V, -1e300, r"state\.v .* -1e\+300"),
                               (S_X, 1e13, r"state\.x must lie within"),
                               (S_T, 1e17, r"state\.t must lie within .* 1e\+17")):
        plant = state.plant.copy()
        plant[PL_S + slot] = value
        cases.append((plant, match))
    plant = state.plant.copy()
    plant[PL_P + P_XFS] = 1e300
    cases.append((plant, r"invalid plant: xfs must lie within .* 1e\+300"))
    for plant, match in cases:
        with pytest.raises(ValueError, match=match.replace(", ", ".*")):
            put(PlantState(plant, state.command))
    put(state)  # the env is unharmed
    after = env.get_state(1) if vector else env.get_state()
    assert after.plant[:PL_WORK].tobytes() == state.plant[:PL_WORK].tobytes()


def test_set_state_recomputes_the_workspace_caches():
    """Every workspace slot set to garbage (-1e300 was reported as chattering, others
    shifted the next observations by up to 104) restores the same plant: the caches are
    recomputed from the state, the settings are the environment's own."""
    env = StickSlipEnv(scene="paper")
    env.reset(seed=3)
    for a in _actions(env, 7):
        env.step(a)
    state = env.get_state()
    acts = _actions(env, 3, seed=1)
    obs0 = env.set_state(state)
    ref = [env.step(a)[:2] for a in acts]
    for k in range(PL_WORK, N_PLANT):
        for value in (-1e300, 104.0, np.nan, 0.0):
            plant = state.plant.copy()
            plant[k] = value
            first = env.set_state(PlantState(plant, state.command))
            assert np.array_equal(first, obs0)
            for a, (obs, reward) in zip(acts, ref, strict=True):
                o, r = env.step(a)[:2]
                assert np.array_equal(o, obs) and abs(r - reward) <= 1e-12, (k, value)


def test_set_state_refuses_a_plant_too_costly_to_step():
    """A restored plant is held to the scan-step caps that reset options are held to."""
    from fricenv.envs.state import PL_P
    from fricenv.params import P_W1

    env = StickSlipEnv(scene="paper")
    env.reset(seed=0)
    state = env.get_state()
    plant = state.plant.copy()
    plant[PL_P + P_W1] = 1e7  # eta: a tone far too fast for one control interval
    fast = PlantState(plant, state.command)
    with pytest.raises(ValueError, match="refused state"):
        env.set_state(fast)
    assert env.set_state(state) is not None  # the env is unharmed
    vec = StickSlipVectorEnv(num_envs=1000, scene="paper")
    vec.reset(seed=0)
    plant[PL_P + P_W1] = 1e5  # within one plant's cap, beyond a thousand plants' share
    with pytest.raises(ValueError, match="MAX_VECTOR_SCAN_STEPS"):
        vec.set_state(3, PlantState(plant, state.command))


def test_vector_state_arrays_and_set_state_cancel_a_pending_reset():
    vec = StickSlipVectorEnv(num_envs=3, scene="self_excited", max_episode_steps=4)
    vec.reset(seed=1)
    for a in _actions(vec, 3):
        vec.step(a)
    keep = vec.get_state(0)
    vec.step(_actions(vec, 1)[0])  # every episode ends here (truncation)
    assert vec._autoreset.all()
    vec.set_state(0, keep)
    plants, cmds = vec.state_arrays()
    assert plants.shape == (3, N_PLANT) and cmds.shape == (3, 2)
    # (the workspace's caches are recomputed from the state, not restored)
    assert plants[0, :PL_WORK].tobytes() == keep.plant[:PL_WORK].tobytes()
    _, _, _, trunc, _ = vec.step(_actions(vec, 1, seed=4)[0])
    assert trunc[0] and vec.get_state(0).episode_steps == 4  # stepped, not reset


# -- batch rollout --------------------------------------------------------------------------
@pytest.mark.parametrize("kw", [{"scene": "self_excited"}, {"scene": "stribeck"},
                                {"scene": "paper", "actuator_lag": 0.5, "actuator_rate": 0.1,
                                 "incremental": True}])
def test_batch_rollout_equals_sequential_single_env_rollouts(kw):
    env = StickSlipEnv(**kw)
    env.reset(seed=21)
    for a in _actions(env, 9):
        env.step(a)
    state = env.get_state()
    k, h = 5, 8
    acts = np.random.default_rng(5).uniform(-1, 1, (k, h, env.action_space.shape[0]))
    rewards, stick = rollout_batch(env, state, acts.astype(np.float32))
    for j in range(k):
        env.set_state(state)
        for t in range(h):
            _, r, _, _, info = env.step(acts[j, t].astype(np.float32))
            assert rewards[j, t] == r and stick[j, t] == info["stick_fraction"]
    serial = BatchRollout(env, k, h, parallel=False).run(state, acts.astype(np.float32))
    assert np.array_equal(serial.rewards, rewards) and np.all(serial.status == 0)


def test_batch_rollout_from_many_states_and_its_checks():
    vec = StickSlipVectorEnv(num_envs=3, scene="viscous", randomize=True)
    vec.reset(seed=2)
    plants, cmds = vec.state_arrays()
    roll = BatchRollout(vec, 6, 4)
    acts = np.zeros((6, 4, 2))
    out = roll.run((plants, cmds), acts, sources=np.array([0, 1, 2, 2, 1, 0]))
    assert np.array_equal(out.rewards[0], out.rewards[5])
    assert np.array_equal(out.rewards[2], out.rewards[3])
    assert not np.array_equal(out.rewards[0], out.rewards[2])  # other plants
    single = BatchRollout(vec, 6, 4).run(vec.get_state(1), acts)
    assert np.array_equal(single.rewards[0], out.rewards[1])
    with pytest.raises(ValueError, match="sources"):
        roll.run((plants, cmds), acts)
    with pytest.raises(ValueError, match=r"shape \(6, 4, 2\)"):
        roll.run((plants, cmds), acts[:, :3], sources=np.zeros(6, np.int64))
    nan = acts.copy()
    nan[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        roll.run(vec.get_state(0), nan)
    with pytest.raises(TypeError, match="PlantState"):
        roll.run(plants, acts)
    with pytest.raises(TypeError, match="fricenv environment"):
        BatchRollout(object(), 2, 2)
    # a sample that leaves the observation box stops there, as the env terminates
    small = StickSlipEnv(scene=SCENES["paper"].replace(x_limit=3.0))
    small.reset(seed=0, options={"x0": 2.9, "v0": 5.0})
    res = BatchRollout(small, 1, 5).run(small.get_state(), np.zeros((1, 5, 1)))
    assert res.status[0] == STATUS_LEFT_BOX and res.length[0] == 1
    assert np.all(res.rewards[0, 1:] == 0.0)
