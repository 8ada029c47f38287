"""Runs whose motion runs away are reported as diverged, never as statistics."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fricenv
from fricenv import divergence
from fricenv.layout import (
    STATUS_DIVERGED,
    STATUS_OK,
)
from fricenv.params import OscillatorParams
from fricenv.regimes import Regime
from fricenv.simulate import SimulationError, run_stats, simulate
from fricenv.sweep import cell_statistics, regime_map

#: lam = 0 and b1 = 1: slip with negative net damping; by t = 1e3 the state is ~1e218 and
#: the integral of (v - V)^2 overflowed (it was returned as inf with status OK).
RUNAWAY = OscillatorParams(lam=0.0, b1=1.0, u0=10.0, nu=0.3)


@pytest.mark.parametrize("call", [lambda: run_stats(RUNAWAY, 1e3),
                                  lambda: simulate(RUNAWAY, 1e3, dt_out=1.0),
                                  lambda: simulate(RUNAWAY, 1e3, dt_out=1.0, method="rk4")],
                         ids=["run_stats", "simulate", "simulate-rk4"])
def test_a_runaway_run_raises_instead_of_returning_inf(call) -> None:
    with pytest.raises(SimulationError, match="the motion diverged by t = 1000") as info:
        call()
    assert info.value.status == STATUS_DIVERGED
    assert "negative net damping" in str(info.value)


def test_a_runaway_continued_from_a_state_is_caught_too() -> None:
    s = run_stats(RUNAWAY, 20.0)  # still moderate: a result
    assert math.isfinite(s.vr2_integral) and s.v_max < 1e8
    with pytest.raises(SimulationError) as info:
        run_stats(RUNAWAY, 980.0, state=s.state)
    assert info.value.status == STATUS_DIVERGED


@pytest.mark.parametrize(("lam", "b1", "u0", "nu"), [(0.0, 1.0, 10.0, 0.3),
                                                      (0.5, 1.0, 10.0, 0.3),
                                                      (0.5, 2.0, 1.0, 0.3),
                                                      (0.1, 1.0, 2.0, 1.5)])
def test_a_runaway_cell_is_labelled_diverged(lam: float, b1: float, u0: float, nu: float
                                             ) -> None:
    """Such cells were labelled WM2 with v_max up to 1e68 and status OK."""
    m = regime_map(OscillatorParams(lam=lam, b1=b1), [u0], [nu], progress=False)
    assert m.labels[0, 0] == Regime.DIVERGED and m.status[0, 0] == STATUS_DIVERGED


def test_a_bounded_plant_with_negative_damping_near_the_belt_is_not_diverged() -> None:
    # b1 > lam, but stick-slip keeps the motion small
    labels, stats, _, status = cell_statistics([OscillatorParams(lam=0.5, b1=0.6, u0=1.0,
                                                                 nu=0.3)])
    assert status[0] == STATUS_OK and labels[0] == Regime.SSM1 and stats[0, 5] < 10


def test_an_env_step_whose_reward_overflows_raises() -> None:
    """The state stayed finite (~7e155) but the interval's (v - V)^2 overflowed: the step
    returned a NaN reward and an inf variance."""
    env = gym.make("fricenv/StickSlip-v0").unwrapped
    env.reset(seed=0, options={"lam": 0.0, "b1": 685.5031072611627})
    with pytest.raises(RuntimeError, match="plant diverged"):
        env.step(np.zeros(1, np.float32))
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(1, np.float32))


def test_a_vector_step_whose_reward_overflows_raises() -> None:
    venv = gym.make_vec("fricenv/StickSlip-v0", num_envs=3,
                        vectorization_mode="vector_entry_point")
    venv.reset(seed=0)
    venv.reset(options={"lam": 0.0, "b1": 685.5031072611627,
                        "reset_mask": np.array([False, True, False])})
    with pytest.raises(RuntimeError, match="plant 1 diverged"):
        venv.step(np.zeros((3, 1), np.float32))
    with pytest.raises(gym.error.ResetNeeded, match="plant 1"):
        venv.step(np.zeros((3, 1), np.float32))


# -- the bound itself ---------------------------------------------------------------------
def test_motion_scale_and_limit() -> None:
    P = OscillatorParams(u0=2.0, xfs=4.0, V=3.0, lam=0.5, b1=0.2, b3=0.16).to_array()
    assert divergence.motion_scale(P, 0.0, 0.0) == pytest.approx(0.16 * 27)
    assert divergence.motion_scale(P, -50.0, 0.0) == 50.0
    assert divergence.motion_limit(P, 0.0, 0.0, 0.5) == pytest.approx(
        divergence.DIVERGENCE_FACTOR * 0.16 * 27)
    band = OscillatorParams(lam=0.0, b1=1.0, b3=1e-6).to_array()  # anti-damped out to 1e3
    assert divergence.motion_scale(band, 0.0, 0.0) == pytest.approx(1e3)
    huge = OscillatorParams(lam=0.0, b1=1e12, b3=1e-300).to_array()
    assert divergence.motion_limit(huge, 0.0, 0.0, 1.0) == divergence.MOTION_CEILING


_damped_law = st.one_of(
    st.tuples(st.floats(0.0, 1.0), st.just(0.0)),  # b1 <= lam is checked below
    st.tuples(st.floats(-1.0, 2.0), st.floats(1e-3, 1.0)))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(lam=st.floats(0.0, 3.0), law=_damped_law, u0=st.floats(0.0, 20.0),
       nu=st.floats(0.0, 3.0), eta=st.floats(0.05, 3.0), V=st.floats(0.0, 3.0),
       x0=st.floats(-20.0, 20.0), v0=st.floats(-20.0, 20.0), span=st.floats(0.5, 60.0))
def test_plants_that_damp_large_speeds_stay_within_the_energy_bound(
        lam, law, u0, nu, eta, V, x0, v0, span) -> None:
    """The energy argument of fricenv.divergence: sqrt(x^2 + v^2) <= 6 scale max(1, t)
    for slip that damps large speeds, so DIVERGENCE_FACTOR leaves these plants alone."""
    b1, b3 = law
    if b3 == 0.0:
        b1 = min(b1, lam)
    p = OscillatorParams(lam=lam, b1=b1, b3=b3, u0=u0, nu=nu, eta=eta, V=V)
    state = fricenv.OscillatorState.start(p, x0, v0)
    try:
        s = run_stats(p, span, state=state, rtol=1e-8, atol=1e-10)
    except SimulationError as e:  # chattering or too stiff: not what this is about
        assert e.status != STATUS_DIVERGED
        return
    bound = 6.0 * float(divergence.motion_scale(p.to_array(), x0, v0)) * max(1.0, span)
    assert max(abs(s.x_max), abs(s.x_min), abs(s.v_max), abs(s.v_min)) <= bound
    assert math.isfinite(s.vr2_integral)
