"""Sizes beyond what memory holds are a ValueError naming the argument and its limit, not a
MemoryError after trying to allocate them."""

from __future__ import annotations

import re

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


def test_simulate_beyond_max_outputs_is_refused_before_allocating() -> None:
    """t_span = 1e6 at dt_out = 0.01 (1e8 instants) allocated 1.7 GB, then ran out of step
    budget; the cap is checked on the instant count, before anything is allocated."""
    from fricenv.simulate import MAX_OUTPUTS

    p = fricenv.OscillatorParams(u0=1.5)
    for span in (1e6, MAX_OUTPUTS * 0.01):  # the cap itself: its grid holds cap + 1 instants
        with pytest.raises(ValueError, match=r"dt_out = 0\.01 asks for .* output instants .* "
                                             + re.escape(f"(at most {MAX_OUTPUTS:g})")):
            fricenv.simulate(p, span, dt_out=0.01)


@pytest.mark.parametrize("method", ["exact", "event"])
def test_output_instants_do_not_consume_the_step_budget(method: str) -> None:
    """The closed form cuts a step at every output instant, and those steps counted against
    the budget: simulate(u0=1.5) over 1.2e5 at dt_out = 0.01 ran 9 s, then raised 'slip far
    stiffer than the model's scale'. Here 1e4 instants against a budget of 2000 steps; the
    run is charged what run_stats is charged, so the budget still holds."""
    p = fricenv.OscillatorParams(u0=1.5)
    stats = fricenv.run_stats(p, 100.0, method=method)
    assert stats.n_steps < 1000  # the motion itself is well within the budget
    traj = fricenv.simulate(p, 100.0, dt_out=0.01, method=method, max_steps=2000)
    assert traj.t.shape == (10001,)
    assert traj.stats.n_steps > 2000 or method == "event"  # the grid's steps are still taken
    assert traj.stats.n_stick == stats.n_stick
    end = traj.final_state
    assert end.mode == stats.state.mode and abs(end.x - stats.state.x) < 1e-9
    if method == "event":  # (its outputs never cut a step)
        return
    tight = 201  # above the 200 scan steps, below the steps the motion takes
    assert stats.n_steps > tight
    for call in (fricenv.run_stats, fricenv.simulate):
        with pytest.raises(fricenv.SimulationError, match="budget"):
            call(p, 100.0, method=method, max_steps=tight)
    with pytest.raises(fricenv.SimulationError, match="budget"):
        fricenv.simulate(p, 100.0, dt_out=0.01, method=method, max_steps=tight)


def test_output_instants_that_collide_in_float64_are_refused() -> None:
    """From t = 1e15 a 10-unit run returned 101 output times, 81 of them distinct, with no
    warning; doubles are 1.2e-4 apart at t = 1e12, so a grid of 1e-4 collides there."""
    p = fricenv.OscillatorParams(u0=1.5)
    start = fricenv.OscillatorState(t=1e12)
    with pytest.raises(ValueError, match=r"dt_out = 0\.0001 is too fine for a start at "
                                         r"state\.t = 1000000000000\.0: output instants \d+ "
                                         r"and \d+ are both"):
        fricenv.simulate(p, 0.01, state=start, dt_out=1e-4)
    with pytest.raises(ValueError, match=r"state\.t must lie within \+-1e\+12"):
        fricenv.simulate(p, 10.0, state=fricenv.OscillatorState(t=1e15))
    traj = fricenv.simulate(p, 10.0, state=start, dt_out=0.1)
    assert np.all(np.diff(traj.t) > 0.0) and traj.t.shape == (101,)
