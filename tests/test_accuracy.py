"""Accuracy of the solvers against closed forms and an independent SciPy event solver.

Run ``pytest -s tests/test_accuracy.py`` to see the measured differences. The reference
solutions are independent of ``fricenv.core``: ``closed_forms.py`` (textbook formulas per
damping case) and :mod:`fricenv.testing.scipy_reference` (DOP853 + events, written from
docs/model.md).
"""

from __future__ import annotations

import functools
import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from closed_forms import slip_phase_params  # noqa: E402

from fricenv.layout import EVENT_STICK  # noqa: E402
from fricenv.params import PAPER_CASES as PAPER_OVERRIDES  # noqa: E402
from fricenv.params import OscillatorParams  # noqa: E402
from fricenv.simulate import OscillatorState, simulate  # noqa: E402
from fricenv.testing.scipy_reference import (  # noqa: E402
    reference_run,
    reference_solution,
)

T_END = 200.0
C = OscillatorParams.preset

#: The paper's Coulomb time-history cases (``fricenv.params.PAPER_CASES``), from rest.
PAPER_CASES: dict[str, OscillatorParams] = {
    f"fig{name}": OscillatorParams(**kw) for name, kw in PAPER_OVERRIDES.items()
}
#: Nonlinear laws (event method only), one of them self-excited without forcing.
NONLINEAR_CASES: dict[str, OscillatorParams] = {
    "stribeck": C("stribeck", eta=0.6, nu=0.1, u0=1.15),
    "viscous": C("viscous", eta=0.6, nu=0.1, u0=1.15),
    "selfexc": C("stribeck", lam=0.1, V=0.3),
}
#: Pure-slip Coulomb runs: V = 50 is never reached, so the phase s = -1 lasts throughout.
PURE_SLIP_CASES: dict[str, OscillatorParams] = {
    "underdamped": C("coulomb", lam=0.5, eta=0.6, nu=0.1, u0=1.15, V=50.0),
    "critical": C("coulomb", lam=2.0, eta=0.6, nu=0.1, u0=1.15, V=50.0),
    "overdamped": C("coulomb", lam=3.0, eta=0.6, nu=0.1, u0=1.15, V=50.0),
    "resonant2": C("coulomb", lam=0.0, eta=1.0, nu=1.0, u0=0.1, V=50.0),
    "resonant1": C("coulomb", lam=0.0, eta=1.0, nu=0.7, u1=0.1, u2=0.3, V=50.0),
}
PURE_X0, PURE_V0 = 0.3, -0.2

#: Bound on max |x| difference to the SciPy reference (which is itself good to ~1e-11).
SCIPY_X_TOL = 1e-7
SCIPY_EVENT_T_TOL = 1e-7


@functools.cache
def _reference(name: str, x0: float = 0.0, v0: float = 0.0):
    """SciPy reference on the output grid of ``simulate`` (computed once per case)."""
    params = {**PAPER_CASES, **NONLINEAR_CASES, **PURE_SLIP_CASES}[name]
    grid = np.linspace(0.0, T_END, int(round(T_END / 0.1)) + 1)
    return reference_solution(params, T_END, x0=x0, v0=v0, t_eval=grid)


def _on_grid(traj, t_ref: np.ndarray) -> np.ndarray:
    """x of a trajectory on the reference grid (checks that the grids coincide)."""
    assert traj.t.shape == t_ref.shape, (traj.t.shape, t_ref.shape)
    np.testing.assert_allclose(traj.t, t_ref, rtol=0, atol=1e-9)
    return np.asarray(traj.x)


def _event_list(traj) -> list[tuple[float, int]]:
    return [(float(t), int(k)) for t, k in zip(traj.event_t, traj.event_kind, strict=True)]


def _compare_events(got: list[tuple[float, int]], ref: list[tuple[float, int]],
                    label: str) -> float:
    """Assert same sequence of event kinds; return max |time difference|."""
    kinds_got = [k for _, k in got]
    kinds_ref = [k for _, k in ref]
    assert kinds_got == kinds_ref, f"{label}: event kinds differ\n got {got}\n ref {ref}"
    if not got:
        return 0.0
    return max(abs(a[0] - b[0]) for a, b in zip(got, ref, strict=True))


# --------------------------------------------------------------------------------------
# references against each other (no kernel needed)
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(PURE_SLIP_CASES))
def test_closed_forms_match_scipy_reference(name: str) -> None:
    """The two references agree, so neither carries a sign or phase slip of its own."""
    p = PURE_SLIP_CASES[name]
    t, x, v, mode, events = _reference(name, PURE_X0, PURE_V0)
    xc, vc = slip_phase_params(t, p, s=-1, x0=PURE_X0, v0=PURE_V0)
    assert events == [] and np.all(mode == -1)
    scale = max(1.0, float(np.abs(xc).max()))
    assert np.abs(x - xc).max() <= 1e-11 * scale
    assert np.abs(v - vc).max() <= 1e-11 * scale


# --------------------------------------------------------------------------------------
# exact solver
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(PURE_SLIP_CASES))
def test_exact_matches_closed_forms_in_pure_slip(name: str) -> None:
    p = PURE_SLIP_CASES[name]
    start = OscillatorState.start(p, PURE_X0, PURE_V0)
    traj = simulate(p, T_END, state=start, dt_out=0.1, method="exact")
    assert traj.n_stick == 0 and len(traj.event_t) == 0 and np.all(traj.mode == -1)
    xc, vc = slip_phase_params(traj.t, p, s=-1, x0=PURE_X0, v0=PURE_V0)
    scale = max(1.0, float(np.abs(xc).max()))
    err_x = float(np.abs(traj.x - xc).max())
    err_v = float(np.abs(traj.v - vc).max())
    print(f"\n[exact vs closed form] {name}: max|dx| = {err_x:.2e}, max|dv| = {err_v:.2e}")
    assert err_x <= 1e-12 * scale
    assert err_v <= 1e-12 * scale


@pytest.mark.parametrize("name", list(PURE_SLIP_CASES))
def test_event_matches_closed_forms_in_pure_slip(name: str) -> None:
    p = PURE_SLIP_CASES[name]
    start = OscillatorState.start(p, PURE_X0, PURE_V0)
    traj = simulate(p, T_END, state=start, dt_out=0.1, method="event")
    assert traj.n_stick == 0 and len(traj.event_t) == 0
    xc, _ = slip_phase_params(traj.t, p, s=-1, x0=PURE_X0, v0=PURE_V0)
    err = float(np.abs(traj.x - xc).max())
    print(f"\n[event vs closed form] {name}: max|dx| = {err:.2e}")
    assert err <= 1e-8 * max(1.0, float(np.abs(xc).max()))


@pytest.mark.parametrize("name", list(PAPER_CASES))
def test_exact_and_event_agree_on_paper_cases(name: str) -> None:
    p = PAPER_CASES[name]
    ex = simulate(p, T_END, dt_out=0.1, method="exact")
    ev = simulate(p, T_END, dt_out=0.1, method="event")
    np.testing.assert_allclose(ex.t, ev.t, rtol=0, atol=1e-12)
    err = float(np.abs(ex.x - ev.x).max())
    dt_ev = _compare_events(_event_list(ex), _event_list(ev), name)
    print(f"\n[exact vs event] {name}: max|dx| = {err:.2e}, max|dt_event| = {dt_ev:.2e}, "
          f"{len(ex.event_t)} events, stick fraction {ex.stick_fraction:.3f}")
    assert err <= 1e-9
    assert dt_ev <= 1e-9


# --------------------------------------------------------------------------------------
# both against the SciPy reference
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["exact", "event"])
@pytest.mark.parametrize("name", list(PAPER_CASES))
def test_paper_cases_match_scipy_reference(name: str, method: str) -> None:
    t, x_ref, _, mode_ref, ev_ref = _reference(name)
    traj = simulate(PAPER_CASES[name], T_END, dt_out=0.1, method=method)
    err = float(np.abs(_on_grid(traj, t) - x_ref).max())
    dt_ev = _compare_events(_event_list(traj), ev_ref, f"{name}/{method}")
    print(f"\n[{method} vs scipy] {name}: max|dx| = {err:.2e}, "
          f"max|dt_event| = {dt_ev:.2e} over {len(ev_ref)} events")
    assert err <= SCIPY_X_TOL
    assert dt_ev <= SCIPY_EVENT_T_TOL


@pytest.mark.parametrize("name", list(NONLINEAR_CASES))
def test_nonlinear_laws_match_scipy_reference(name: str) -> None:
    t, x_ref, _, _, ev_ref = _reference(name)
    traj = simulate(NONLINEAR_CASES[name], T_END, dt_out=0.1, method="event")
    err = float(np.abs(_on_grid(traj, t) - x_ref).max())
    dt_ev = _compare_events(_event_list(traj), ev_ref, name)
    print(f"\n[event vs scipy] {name}: max|dx| = {err:.2e}, "
          f"max|dt_event| = {dt_ev:.2e} over {len(ev_ref)} events")
    assert err <= SCIPY_X_TOL
    assert dt_ev <= SCIPY_EVENT_T_TOL


def test_auto_method_is_accurate_for_every_law() -> None:
    """Whatever "auto" picks, it must be as good as the reference bound."""
    for name, p in (("fig5a", PAPER_CASES["fig5a"]), ("stribeck", NONLINEAR_CASES["stribeck"])):
        t, x_ref, _, _, ev_ref = _reference(name)
        traj = simulate(p, T_END, dt_out=0.1)
        assert np.abs(_on_grid(traj, t) - x_ref).max() <= SCIPY_X_TOL
        assert _compare_events(_event_list(traj), ev_ref, name) <= SCIPY_EVENT_T_TOL


@pytest.mark.parametrize(
    "lam, eta, nu",
    [(0.0, 49.0, 1.0 / 49.0),  # nu * eta one ulp short of resonance
     (0.0, 1.0 + 1e-9, 0.3), (1e-12, 1.0, 0.3), (1e-160, 1.0, 0.3)],
)
def test_near_resonance_is_accurate(lam: float, eta: float, nu: float) -> None:
    """A tone within rounding reach of resonance (not on it) made the closed form cancel
    its own digits: a spurious "chattering" error or x off by O(1). The exact method now
    hands such calls to the event method, and says so in the result's method."""
    from fricenv import core
    from fricenv.layout import METHOD_EVENT, METHOD_EXACT, N_STATS
    from fricenv.simulate import OscillatorState

    p = C("coulomb", lam=lam, eta=eta, nu=nu, u0=0.5, xfk=0.5, xfs=0.8)
    t_end = 60.0
    t, x_ref, _, _, ev_ref = reference_solution(p, t_end, t_eval=np.arange(601) * 0.1)
    for method in ("auto", "exact"):
        traj = simulate(p, t_end, dt_out=0.1, method=method)
        assert traj.method == "event"
        assert np.abs(_on_grid(traj, t) - x_ref).max() <= SCIPY_X_TOL
        assert _compare_events(_event_list(traj), ev_ref, "near resonance") <= SCIPY_EVENT_T_TOL
    # the kernels fall back on their own (an environment or a sweep passes METHOD_EXACT)
    ends = []
    for code in (METHOD_EXACT, METHOD_EVENT):
        S = OscillatorState.start(p).to_array()
        stats = np.zeros(N_STATS)
        assert core.advance(p.to_array(), S, t_end, stats, code, 1e-10, 1e-12, 10**6,
                            core.new_workspace()) == 0
        ends.append(S)
    np.testing.assert_array_equal(ends[0], ends[1])


def test_exact_resonance_keeps_the_closed_form() -> None:
    """lam = 0 with a tone exactly at w = 1 has its own closed form (x_p ~ tau sin tau)."""
    assert simulate(PURE_SLIP_CASES["resonant1"], 10.0).method == "exact"


# --------------------------------------------------------------------------------------
# grazing: v touches V tangentially
# --------------------------------------------------------------------------------------
def _grazing_setup() -> tuple[OscillatorParams, float, float, float, float]:
    """Fig. 7's periodic orbit and the velocity maximum on it, known to ~1e-13.

    In slip s = -1 the Coulomb dynamics do not depend on V, so the orbit is found on a
    pure-slip run (V = 50): its state at t = 40 pi (the forcing period is 10 pi, the
    transient has decayed by e^-31) starts a run at t = 0 on the orbit. V is then placed
    1e-9 above or below the max of v, which is reached once per period.
    """
    from scipy.optimize import brentq

    base = C("coulomb", eta=0.2, nu=1.0, u0=1.65, V=50.0)
    t_per = 2.0 * math.pi / base.eta
    (seg,) = reference_run(base, 4.0 * t_per).segments
    x0, v0 = (float(z) for z in seg.sol(4.0 * t_per))
    run = reference_run(base, t_per, x0, v0)
    (seg,) = run.segments
    grid = np.linspace(0.0, t_per, 20001)
    i = int(np.argmax(seg.sol(grid)[1]))
    p = run.p
    t_star = brentq(lambda t: p.accel(t, *seg.sol(t), -1), grid[i - 1], grid[i + 1],
                    xtol=1e-15)
    return base, x0, v0, t_star, float(seg.sol(t_star)[1])


@pytest.mark.parametrize("method", ["scipy", "exact", "event"])
def test_grazing_contact_is_detected(method: str) -> None:
    """A dip of 1e-9 through V (crossings ~1e-4 apart) must give a stick at the velocity
    maximum; a maximum 1e-9 short of V must give no contact at all."""
    base, x0, v0, t_star, v_star = _grazing_setup()
    for dv, sticks in ((-1e-9, True), (+1e-9, False)):
        p = base.replace(V=v_star + dv)
        t_end = t_star + 1.0
        if method == "scipy":
            events = reference_run(p, t_end, x0, v0).events
        else:
            start = OscillatorState.start(p, x0, v0)
            traj = simulate(p, t_end, state=start, dt_out=0.1, method=method)
            events = _event_list(traj)
        print(f"\n[grazing/{method}] V = v_max {dv:+.0e}: events {events}, t* = {t_star:.6f}")
        if sticks:
            assert events and events[0][1] == EVENT_STICK, events
            # first crossing is at t* - sqrt(2 dv / |v''|), well within 1e-3 of t*
            assert abs(events[0][0] - t_star) < 1e-3, (events[0][0], t_star)
        else:
            assert not events, (dv, events)


# --------------------------------------------------------------------------------------
# order of convergence of the event method
# --------------------------------------------------------------------------------------
def test_event_error_follows_tolerance() -> None:
    """Error against a tight run falls in proportion to rtol on a pure-slip Stribeck case.

    Started at the slip equilibrium x = xfk - b1 V + b3 V^3 so that v stays below V and the
    run has no switches: the error then measures the Taylor steps alone. Their order grows
    with the tolerance (``core.taylor_order``) and their length is capped, so the step
    count is not a power of the error; what a user relies on is the error tracking rtol.
    """
    p = C("stribeck", eta=0.6, nu=0.1, u0=0.5)
    x0 = p.xfk - p.b1 * p.V + p.b3 * p.V**3
    start = OscillatorState.start(p, x0, 0.0)
    ref = simulate(p, T_END, state=start, dt_out=0.1, method="event", rtol=1e-13,
                   atol=1e-15)
    assert ref.n_stick == 0 and len(ref.event_t) == 0 and float(np.max(ref.v)) < p.V
    _, x_sp, *_ = reference_solution(p, T_END, x0=x0, v0=0.0, t_eval=ref.t)
    assert np.abs(ref.x - x_sp).max() < 1e-10
    rtols = (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
    steps, errs = [], []
    for rtol in rtols:
        tr = simulate(p, T_END, state=start, dt_out=0.1, method="event", rtol=rtol,
                      atol=rtol * 1e-2)
        steps.append(tr.n_steps)
        errs.append(float(np.abs(tr.x - ref.x).max()))
    print("\n[event tolerance] " + ", ".join(
        f"rtol {r:.0e}: {n} steps, err {e:.2e}" for r, n, e in zip(rtols, steps, errs,
                                                                    strict=True)))
    assert all(e <= 10 * r for r, e in zip(rtols, errs, strict=True))
    assert all(b < a for a, b in zip(errs, errs[1:], strict=False))
    assert errs[-1] < 1e-4 * errs[0]


# --------------------------------------------------------------------------------------
# the paper's scheme as a baseline
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["fig5a", "fig5b", "fig6"])
def test_rk4_baseline_misses_stick_slip(name: str) -> None:
    """Fixed-step RK4 with sgn cannot stick: an O(0.1-1) error that refining dt does not
    remove (docs/model.md). Documents why the exact/event solvers exist."""
    p = PAPER_CASES[name]
    ex = simulate(p, T_END, dt_out=0.1, method="exact")
    errs = {}
    for dt in (0.04, 0.01):
        rk = simulate(p, T_END, dt_out=0.1, method="rk4", dt=dt)
        np.testing.assert_allclose(rk.t, ex.t, rtol=0, atol=1e-9)
        assert rk.n_stick == 0 and not np.any(rk.mode == 0)
        errs[dt] = float(np.abs(rk.x - ex.x).max())
    print(f"\n[rk4 vs exact] {name}: " + ", ".join(f"dt={k}: {v:.3f}" for k, v in errs.items()))
    assert ex.n_stick > 0
    assert errs[0.04] > 0.05
    assert errs[0.01] > 0.05  # no convergence to the true (sticking) solution


# --------------------------------------------------------------------------------------
# broad sweep (slow): random parameters, every law, against the SciPy reference
# --------------------------------------------------------------------------------------
@pytest.mark.slow
def test_random_cases_match_scipy_reference() -> None:
    """60 random (law, eta, nu, u0, lam, V) over tau in [0, 100]: same event sequence and
    x within the reference bound, with exact and event alike."""
    rng = np.random.default_rng(1)
    worst = 0.0
    for i in range(60):
        law = ("coulomb", "viscous", "stribeck")[i % 3]
        p = C(law, eta=float(rng.choice([1 / 9, 1 / 5, 0.6, 5 / 3, 7 / 3, 6.0])),
              nu=float(rng.uniform(0.0, 2.0)), u0=float(10 ** rng.uniform(-1.0, 1.3)),
              lam=float(rng.choice([0.05, 0.1, 0.5, 1.0])),
              V=float(rng.choice([0.3, 1.0, 2.0])))
        t, x_ref, _, _, ev_ref = reference_solution(p, 100.0)
        for method in ("exact", "event") if p.is_coulomb else ("event",):
            traj = simulate(p, 100.0, dt_out=0.1, method=method)
            err = float(np.abs(_on_grid(traj, t) - x_ref).max())
            dt_ev = _compare_events(_event_list(traj), ev_ref, f"{i}/{method} {p}")
            assert err <= SCIPY_X_TOL and dt_ev <= SCIPY_EVENT_T_TOL, (i, method, p, err, dt_ev)
            worst = max(worst, err)
    print(f"\n[random sweep] worst max|dx| = {worst:.2e}")


def test_stiff_stretch_goes_back_to_rosenbrock_after_rejections() -> None:
    """From rest at u0 = 1e10, the fast start makes Rosenbrock steps fail at first; the
    stretch must try them again rather than stay on stability-bound Taylor steps for the
    rest of the run (which took 37 s per unit of tau at u0 = 1e12)."""
    from fricenv import run_stats, simulate

    p = C("stribeck", u0=1e10, nu=0.5)
    s = run_stats(p, 1.5)
    # Taylor steps throughout: ~2e6 in a unit of tau, past the default step budget
    ref = simulate(p, 1.5, dt_out=1.5, max_steps_per_tau=1e7)
    assert s.n_steps < 0.01 * ref.n_steps, (s.n_steps, ref.n_steps)
    assert (s.n_reversals, s.n_stick) == (ref.n_reversals, ref.n_stick)
    scale = max(abs(ref.x[-1]), abs(ref.v[-1]))
    assert abs(s.state.x - ref.x[-1]) <= 1e-8 * scale
    assert abs(s.state.v - ref.v[-1]) <= 1e-8 * scale


def _recorded_vr2(p, t_span: float, rtol: float) -> tuple[float, float]:
    """(v - V)^2 integral and step count of the recording path (Taylor steps only, each
    step's polynomial integrated exactly), from rest."""
    from fricenv import OscillatorState, core
    from fricenv.layout import METHOD_EVENT, N_STATS, ST_N_STEPS, ST_VR2_INT

    S = OscillatorState.start(p).to_array()
    stats = np.zeros(N_STATS)
    core.reset_stats(stats)
    two = np.zeros(2)
    rec = core.Recording(np.array([0.0, t_span]), two.copy(), two.copy(), two.copy(),
                         np.zeros(100), np.zeros(100, dtype=np.int8), np.zeros(100),
                         np.zeros(2, np.int64))
    status = core.record(p.to_array(), S, stats, core.Solver(METHOD_EVENT, rtol, rtol, 100),
                         rec, core.new_workspace())
    assert status == 0
    return stats[ST_VR2_INT], stats[ST_N_STEPS]


@pytest.mark.parametrize(("rtol", "tol"), [(1e-6, 1e-6), (1e-8, 1e-9), (1e-10, 1e-9)])
def test_vr2_integral_over_rosenbrock_steps(rtol: float, tol: float) -> None:
    """A Rosenbrock step's share of the (v - V)^2 integral comes from the step's values,
    not from v' and v'' of the equation of motion: in a stiff stretch these carry the
    state's error times |df/dv| h and its square, and the integral was 5.7 times itself
    off at rtol 1e-6 (2.4e-3 at 1e-8). Reference: the recording path's Taylor steps."""
    from fricenv import run_stats

    p = C("stribeck", u0=1e8, nu=0.5)
    ref, ref_steps = _recorded_vr2(p, 1.0, 1e-12)
    s = run_stats(p, 1.0, rtol=rtol, atol=1e-2 * rtol)
    if rtol == 1e-8:
        assert s.n_steps < 0.05 * ref_steps  # (Rosenbrock steps, nearly all)
    assert abs(s.vr2_integral / ref - 1.0) <= tol


@pytest.mark.parametrize("v0", [7e6, 1e10])
def test_slip_too_stiff_for_the_smallest_step_is_an_error(v0: float) -> None:
    """From |v - V| ~ 1e7 with the cubic law the stiff time scale 1 / |df/dv| is below the
    smallest step the time resolution allows (1e-13 at t < 1); the floored Taylor step then
    made a bogus stick at t ~ 1e-13 (the block rode the belt, x 69 % off at tau = 1, status
    OK) or an overflow. Both paths now refuse it; from 1e6 the transient is still resolved
    (from any start this fast, the displacement to v = V differs by < 1e-5)."""
    from fricenv import OscillatorParams, OscillatorState, SimulationError, run_stats, simulate

    p = OscillatorParams.preset("stribeck")
    with pytest.raises(SimulationError, match="stiffer than the smallest step"):
        simulate(p, 1.0, state=OscillatorState.start(p, 0.0, v0), dt_out=1.0)
    with pytest.raises(SimulationError, match="stiffer than the smallest step"):
        run_stats(p, 1.0, state=OscillatorState.start(p, 0.0, v0))
    tr = simulate(p, 1.0, state=OscillatorState.start(p, 0.0, 1e6), dt_out=1.0)
    s = run_stats(p, 1.0, state=OscillatorState.start(p, 0.0, 1e6))
    assert abs(tr.x[-1] - 3.27025) < 1e-5 and abs(s.state.x - 3.27025) < 1e-5


@pytest.mark.parametrize("u0", [2000.0, 5000.0])
def test_stiff_stretches_on_the_stats_path(u0: float) -> None:
    """At large u0 the cubic law's slope makes slip stiff; the stats-only path then takes
    Rosenbrock steps (far fewer than the Taylor steps' stability-limited ones) and still
    agrees with the recording path (Taylor steps throughout) at the same tolerance, switch
    for switch."""
    from fricenv import run_stats, simulate

    p = C("stribeck", eta=1 / 9, u0=u0, nu=1.3)
    s = run_stats(p, 400.0, rtol=1e-6, atol=1e-8)
    tr = simulate(p, 400.0, rtol=1e-6, atol=1e-8, dt_out=400.0)
    ref = simulate(p, 400.0, rtol=1e-11, atol=1e-11, dt_out=400.0)
    assert s.n_steps < 0.6 * tr.n_steps
    assert (s.n_reversals, s.n_stick) == (ref.n_reversals, ref.n_stick)
    scale = max(abs(ref.x[-1]), abs(ref.v[-1]))
    assert abs(s.state.x - ref.x[-1]) <= 1e-5 * scale
    assert abs(s.state.v - ref.v[-1]) <= 1e-5 * scale
