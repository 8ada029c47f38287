"""Sizes beyond what memory holds are a ValueError naming the argument and its limit, not a
MemoryError after trying to allocate them."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import fricenv  # noqa: F401  (registers the environments)
from fricenv.envs.stick_slip import MAX_SAMPLES
from fricenv.envs.vector import MAX_NUM_ENVS, StickSlipVectorEnv


@pytest.mark.parametrize("n", [MAX_NUM_ENVS + 1, 10**12])
def test_a_vector_env_beyond_max_num_envs_is_refused(n: int) -> None:
    """num_envs = 10**12 tried to allocate 7 TiB."""
    with pytest.raises(ValueError, match=rf"num_envs must be an integer <= {MAX_NUM_ENVS}, "
                                         rf"got {n}"):
        gym.make_vec("fricenv/StickSlip-v0", num_envs=n, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="num_envs must be an integer <="):
        StickSlipVectorEnv(num_envs=n)


def test_sample_interval_beyond_max_samples_is_refused() -> None:
    """n_samples = 10**10 tried to allocate 75 GiB."""
    env = gym.make("fricenv/StickSlip-v0").unwrapped
    env.reset(seed=0)
    a = np.zeros(1, np.float32)
    for n in (MAX_SAMPLES + 1, 10**10):
        with pytest.raises(ValueError, match=rf"n_samples must be an integer <= {MAX_SAMPLES}, "
                                             rf"got {n}"):
            env.sample_interval(a, n)
    t, v, stuck = env.sample_interval(a, 5)
    assert t.shape == v.shape == stuck.shape == (5,)


def test_a_vector_step_too_costly_for_its_plants_is_refused() -> None:
    """Each plant was held to MAX_INTERVAL_SCAN_STEPS, but 10,000 plants under a tone at
    eta = 1e5 took minutes a vector step (found by the property suite)."""
    with pytest.raises(ValueError, match=r"num_envs = 1000 plants, at most "
                                         r"MAX_VECTOR_SCAN_STEPS = 1e\+07 scan steps in all"):
        gym.make_vec("fricenv/StickSlip-v0", num_envs=1000,
                     vectorization_mode="vector_entry_point", params={"eta": 1e5})
    venv = gym.make_vec("fricenv/StickSlip-v0", num_envs=1000,
                        vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    with pytest.raises(ValueError, match="change the reset options"):
        venv.reset(options={"eta": 1e5})
    # a refused reset loses nothing: the same seedless reset follows as if it never came
    twin = gym.make_vec("fricenv/StickSlip-v0", num_envs=1000,
                        vectorization_mode="vector_entry_point")
    twin.reset(seed=0)
    np.testing.assert_array_equal(venv.reset()[0], twin.reset()[0])
    small = gym.make_vec("fricenv/StickSlip-v0", num_envs=4,
                         vectorization_mode="vector_entry_point")
    small.reset(seed=0, options={"eta": 1e5})  # 4 plants: within the budget
