"""Periodic orbits, Floquet multipliers and Lyapunov exponents from the exact tangent,
checked against finite differences of the Poincare map and against each other."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fricenv
from fricenv import forcing_period, lyapunov_exponent, periodic_orbit
from fricenv.params import PAPER_CASES, OscillatorParams
from fricenv.simulate import OscillatorState, SimulationError, simulate

FIG7 = OscillatorParams(**PAPER_CASES["7"])  # periodic oscillation without stick
STICK_SLIP = OscillatorParams(eta=0.6, nu=1.0, u0=1.15)  # periodic stick-slip


@pytest.fixture(scope="module")
def orbits():
    return {"fig7": periodic_orbit(FIG7), "stick-slip": periodic_orbit(STICK_SLIP)}


def test_forcing_period():
    assert forcing_period(FIG7) == pytest.approx(2 * math.pi / 0.2)
    assert forcing_period(OscillatorParams(eta=0.6, nu=0.1, u0=1.0)) == pytest.approx(
        2 * math.pi * 10 / 0.6)
    with pytest.raises(ValueError, match="nu = 0.7071"):
        forcing_period(OscillatorParams(eta=0.6, nu=math.sqrt(0.5), u0=1.0))


def test_paper_periodic_cases_are_stable(orbits):
    fig7, ss = orbits["fig7"], orbits["stick-slip"]
    assert fig7.mode != 0 and fig7.stable
    # slip throughout on the Coulomb law: linear, so det M = exp(-lam T) and the complex
    # pair has |mu| = exp(-lam T / 2)
    assert np.abs(fig7.multipliers) == pytest.approx(np.exp(-0.25 * fig7.period), rel=1e-8)
    assert ss.mode == 0 and ss.stable  # held in stick at the section: one multiplier is 0
    assert abs(ss.multipliers[1]) < 1e-12 < abs(ss.multipliers[0]) < 1.0
    tr = simulate(STICK_SLIP, ss.period, state=OscillatorState.start(STICK_SLIP, ss.x, ss.v))
    assert tr.n_stick >= 1
    assert (tr.x[-1], tr.v[-1]) == pytest.approx((ss.x, ss.v), abs=1e-9)


@pytest.mark.parametrize("name", ["fig7", "stick-slip"])
def test_monodromy_matches_differences_of_the_poincare_map(orbits, name):
    o = orbits[name]
    h = 1e-6
    free = (0,) if o.mode == 0 else (0, 1)
    for i in free:
        ends = []
        for sgn in (1.0, -1.0):
            y = np.array([o.x, o.v])
            y[i] += sgn * h
            tr = simulate(o.params, o.period, dt_out=o.period, rtol=1e-12, method="event",
                          state=OscillatorState.start(o.params, y[0], y[1]))
            ends.append(np.array([tr.x[-1], tr.v[-1]]))
        fd = (ends[0] - ends[1]) / (2 * h)
        np.testing.assert_allclose(o.monodromy[:, i], fd, rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("name", ["fig7", "stick-slip"])
def test_lyapunov_exponent_of_an_orbit_is_log_mu_over_T(orbits, name):
    o = orbits[name]
    le = lyapunov_exponent(o.params, 60 * o.period, transient=20 * o.period,
                           renorm=o.period)
    assert le.exponent == pytest.approx(o.lyapunov_exponent, abs=1e-3)
    assert le.time == pytest.approx(60 * o.period)


def test_lyapunov_exponent_is_zero_along_the_flow_of_a_self_excited_cycle():
    """Unforced, the system is autonomous: a shift along the stick-slip limit cycle
    neither grows nor decays (the stick phases absorb every other perturbation)."""
    p = OscillatorParams(lam=0.05, u0=0.0)
    le = lyapunov_exponent(p, 2000.0, transient=500.0)
    assert abs(le.exponent) < 1e-3
    assert simulate(p, 100.0, state=le.state).n_stick > 0


def test_refusals():
    with pytest.raises(ValueError, match="periods"):
        periodic_orbit(FIG7, periods=0)
    with pytest.raises(ValueError, match="renorm"):
        lyapunov_exponent(FIG7, 10.0, renorm=-1.0)
    with pytest.raises(SimulationError, match="did not converge"):
        periodic_orbit(OscillatorParams(eta=0.6, nu=0.5, u0=2.0), max_iter=1,
                       transient=0)


@pytest.mark.parametrize("case", ["5a", "5b", "6"])
def test_paper_stick_slip_cases_lock_onto_stable_orbits(case):
    """The paper's stick-slip cases (Figs. 5a, 5b, 6; nu = 1/10, 1/5, 23/20) settle on a
    periodic stick-slip response of their forcing period, and it is stable."""
    p = OscillatorParams(**PAPER_CASES[case])
    o = periodic_orbit(p, transient=100)
    assert o.stable and o.residual <= 1e-10
    tr = simulate(p, o.period, state=OscillatorState.start(p, o.x, o.v))
    assert tr.n_stick >= 1


def test_lyapunov_is_a_statistic_of_maps_cells_and_atlases(tmp_path):
    """regime_map, cell_statistics and the atlas measure it on request, from each cell's
    own start, transient and window, and a saved map keeps it."""
    p = OscillatorParams.preset("stribeck", eta=0.6)
    u0, nu = np.array([0.5, 3.0, 30.0]), np.array([0.5, 1.0])
    m = fricenv.regime_map(p, u0=u0, nu=nu, lyapunov=True)
    assert np.all(np.isfinite(m.lyapunov)) and np.all(m.lyapunov < 0.0)
    plain = fricenv.regime_map(p, u0=u0, nu=nu)
    assert np.all(np.isnan(plain.lyapunov))
    np.testing.assert_array_equal(plain.labels, m.labels)
    m.save(tmp_path / "m.npz")
    np.testing.assert_array_equal(fricenv.RegimeMap.load(tmp_path / "m.npz").lyapunov,
                                  m.lyapunov)
    cell = p.replace(u0=3.0, nu=1.0)
    labels, _, _, _, exponent = fricenv.cell_statistics([cell], lyapunov=True)
    assert exponent[0] == m.lyapunov[1, 1] and labels[0] == m.labels[1, 1]
    assert len(fricenv.cell_statistics([cell])) == 4
    ds = fricenv.atlas(p, {"u0": u0, "nu": nu}, path=tmp_path / "a.zarr", progress=False,
                       settings=fricenv.SweepSettings(lyapunov=True))
    np.testing.assert_array_equal(ds["lyapunov"].values, m.lyapunov)
