"""Per-plant reset options of the vector env: an option may be a numpy array of one value
per plant, through ``reset``, ``reset_plants``, the SB3 adapter and ``gym.make_vec``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fricenv  # noqa: F401  (registers the environments)
from fricenv.envs.sb3 import StickSlipSB3VecEnv
from fricenv.envs.stick_slip import StickSlipEnv
from fricenv.envs.vector import StickSlipVectorEnv

SENSORS = {"obs_noise": {"x": 0.05, "v_rel": 0.1}, "obs_delay": 2}
ENV_ID = "fricenv/StickSlipSelfExcited-v0"


def _actions(env, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.0, 1.0, (n, *env.action_space.shape)).astype(np.float32)


def _states(vec):
    return [vec.get_state(i) for i in range(vec.num_envs)]


@st.composite
def _plant_sweeps(draw):
    n = draw(st.integers(1, 4))
    reals = st.floats(0.0, 1.0, allow_nan=False)
    u = np.array(draw(st.lists(st.tuples(reals, reals, reals), min_size=n, max_size=n)))
    options = {"lam": 0.02 + 0.4 * u[:, 0], "x0": 2.0 * u[:, 1] - 1.0,
               "obs_noise_scale": 2.0 * u[:, 2],
               "obs_delay": np.array(draw(st.lists(st.integers(0, 2), min_size=n,
                                                   max_size=n)))}
    mask = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    return options, mask, draw(st.integers(0, 1000))


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_plant_sweeps())
def test_array_options_equal_per_plant_scalar_resets_bit_for_bit(sweep):
    options, mask, seed = sweep
    n = mask.size
    vec = StickSlipVectorEnv(num_envs=n, scene="self_excited", max_episode_steps=50, **SENSORS)
    singles = [StickSlipEnv(scene="self_excited", **SENSORS) for _ in range(n)]
    obs, _ = vec.reset(seed=seed, options=options)
    for i, env in enumerate(singles):
        scalar = {key: value[i] for key, value in options.items()}
        assert np.array_equal(obs[i], env.reset(seed=seed + i, options=scalar)[0])
    acts = _actions(vec, 6, seed)
    for a in acts:
        o, r, *_ = vec.step(a)
        for i, env in enumerate(singles):
            o1, r1, *_ = env.step(a[i])
            assert np.array_equal(o[i], o1) and r[i] == r1
    if not mask.any():
        return
    # with a mask: only the masked plants take (and check) their elements
    masked = {key: value.astype(np.float64) for key, value in options.items()}
    masked["obs_delay"] = options["obs_delay"]
    for value in masked.values():
        if value.dtype == np.float64:
            value[~mask] = np.nan
    before = _states(vec)
    obs, _ = vec.reset(options={"reset_mask": mask, **masked})
    for i, env in enumerate(singles):
        if mask[i]:
            scalar = {key: value[i] for key, value in options.items()}
            assert np.array_equal(obs[i], env.reset(options=scalar)[0])
        else:
            assert vec.get_state(i).same_as(before[i])


def test_refused_array_option_names_the_plant_and_changes_no_plant():
    vec = StickSlipVectorEnv(num_envs=4, scene="self_excited", **SENSORS)
    vec.reset(seed=0)
    before = _states(vec)
    lams = np.array([0.1, 0.2, -1.0, 0.3])
    for options, err, match in (
        ({"lam": lams}, ValueError, r"plant 2: .*lam.*-1\.0"),
        ({"obs_delay": np.array([0, 1, 2, 3])}, ValueError, r"plant 3: .*obs_delay.*got 3$"),
        ({"obs_delay": np.array([0.0, 1.0, 2.0, 1.0])}, TypeError, r"plant 0: .*obs_delay"),
        ({"obs_noise_scale": np.array([1.0, np.inf, 1.0, 1.0])}, ValueError,
         r"plant 1: .*obs_noise_scale"),
        ({"lam": np.ones(3)}, ValueError, r"'lam'.*shape \(4,\).*got shape \(3,\)"),
        ({"lam": np.ones((4, 1))}, ValueError, r"'lam'.*got shape \(4, 1\)"),
        ({"lam": np.array([0.1, 0.2, 0.3, 0.4]), "xfs": np.array([4.0, 4.0, 4.0, 1.0])},
         ValueError, r"plant 3: "),
    ):
        with pytest.raises(err, match=match):
            vec.reset(options=options)
        assert all(vec.get_state(i).same_as(s) for i, s in enumerate(before)), options
    # an unmasked plant's element is not used, so not checked
    vec.reset(options={"reset_mask": np.array([True, True, False, True]), "lam": lams})
    assert [vec.get_state(i).params["lam"] for i in (0, 1, 3)] == [0.1, 0.2, 0.3]
    assert vec.get_state(2).same_as(before[2])
    # a 0-d array is no array of values per plant: refused as the single env refuses it
    with pytest.raises(TypeError, match="real number, got array"):
        vec.reset(options={"lam": np.array(0.25)})
    with pytest.raises(TypeError, match="real number, got array"):
        StickSlipEnv(scene="self_excited").reset(options={"lam": np.array(0.25)})


def test_reset_plants_sb3_and_make_vec_pass_array_options_through():
    n = 3
    xfs = np.array([3.0, 3.5, 4.5])
    ref = StickSlipVectorEnv(num_envs=n, scene="self_excited")
    ref.reset_plants([7 + i for i in range(n)], [{"xfs": x} for x in xfs])
    want = _states(ref)
    vec = StickSlipVectorEnv(num_envs=n, scene="self_excited")
    vec.reset_plants([7 + i for i in range(n)], [{"xfs": xfs}] * n)
    assert all(vec.get_state(i).same_as(s) for i, s in enumerate(want))
    with pytest.raises(ValueError, match=r"plant 1: .*xfs"):
        vec.reset_plants([None] * n, [None, {"xfs": np.ones(2)}, None])
    made = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point")
    made.reset(seed=7, options={"xfs": xfs})
    assert all(made.unwrapped.get_state(i).same_as(s) for i, s in enumerate(want))
    sb3 = StickSlipSB3VecEnv(num_envs=n, scene="self_excited")
    sb3.seed(7)
    sb3.set_options({"xfs": xfs})
    obs = sb3.reset()
    assert all(sb3.venv.get_state(i).same_as(s) for i, s in enumerate(want))
    assert np.array_equal(obs, ref.reset_plants([7, 8, 9], [{"xfs": x} for x in xfs])[0])
    sb3.reset()  # the options were for one reset
    assert [sb3.venv.get_state(i).params["xfs"] for i in range(n)] == [4.0] * n
