"""Forward sensitivities (``simulate(wrt=...)``, ``run_stats(wrt=...)``), checked against
what they were not built from: central finite differences of the plain simulator (where
the switching sequence is the same at +-h) and of the independent SciPy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from fricenv.params import OscillatorParams
from fricenv.simulate import OscillatorState, run_stats, simulate
from fricenv.testing.scipy_reference import reference_solution

T = 30.0
X0, V0 = 0.3, 1.4
H = 1e-6
RTOL = 1e-12

CASES = {
    "coulomb": (OscillatorParams(u0=1.15, nu=0.1),
                ("xfk", "xfs", "lam", "u0", "eta", "nu", "V", "x0", "v0", "b1", "b3")),
    "viscous, reversals": (OscillatorParams.preset("viscous", u0=4.0, nu=1.7),
                           ("b1", "xfs", "xfk", "V", "u1", "u2", "x0")),
    "stribeck": (OscillatorParams.preset("stribeck", u0=2.0, nu=0.5),
                 ("b1", "b3", "xfs", "lam", "v0")),
    "exponential, delta 2": (OscillatorParams.preset("exponential", u0=4.0, nu=1.7),
                             ("vs", "cv", "xfs", "xfk", "V", "eta")),
    "exponential, delta 1, cv 0": (
        OscillatorParams.preset("exponential", u0=1.5, nu=0.37, delta=1.0, cv=0.0),
        ("vs", "cv", "xfs", "xfk", "lam")),
}


def _moved(p: OscillatorParams, name: str, dh: float, method: str = "event"):
    """The plain run with parameter ``name`` moved by ``dh``."""
    x0, v0 = X0 + dh * (name == "x0"), V0 + dh * (name == "v0")
    if name not in ("x0", "v0"):
        value = {"u1": p.amp1, "u2": p.amp2}.get(name, getattr(p, name))
        p = p.replace(**{name: value + dh})
    return simulate(p, T, state=OscillatorState.start(p, x0=x0, v0=v0), method=method,
                    rtol=RTOL)


def _central(p: OscillatorParams, name: str, h: float, method: str = "event"):
    """Central differences of x and v, and whether the switching sequence held at +-h
    (one-sided, of second order, at a parameter's lower bound 0)."""
    if name == "cv" and p.cv == 0.0:
        a0, a1, a2 = (_moved(p, name, k * h, method) for k in (0, 1, 2))
        same = bool(np.all(a1.event_kind == a2.event_kind))
        return ((-3 * a0.x + 4 * a1.x - a2.x) / (2 * h),
                (-3 * a0.v + 4 * a1.v - a2.v) / (2 * h), same)
    a, b = _moved(p, name, h, method), _moved(p, name, -h, method)
    same = (a.event_kind.shape == b.event_kind.shape
            and bool(np.all(a.event_kind == b.event_kind)))
    return (a.x - b.x) / (2 * h), (a.v - b.v) / (2 * h), same


def _tangent(p: OscillatorParams, wrt: tuple[str, ...]):
    return simulate(p, T, state=OscillatorState.start(p, x0=X0, v0=V0), wrt=wrt, rtol=RTOL)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


@pytest.mark.parametrize("case", sorted(CASES))
def test_matches_central_differences(case):
    p, wrt = CASES[case]
    tr = _tangent(p, wrt)
    assert tr.dx_dp.shape == (tr.t.shape[0], len(wrt)) == tr.dv_dp.shape
    assert tr.event_t_dp.shape == (tr.event_t.shape[0], len(wrt))
    assert tr.singular.shape == (0,)
    assert tr.event_t.shape[0] >= 3  # the derivative crossed switches
    for j, name in enumerate(wrt):
        fx, fv, same = _central(p, name, H)
        assert same, name
        assert _rel(tr.dx_dp[:, j], fx) < 1e-6, name
        assert _rel(tr.dv_dp[:, j], fv) < 1e-6, name


def test_coulomb_tangent_matches_closed_form_differences():
    """Both methods: the event method's tangent against differences of the closed form."""
    p, wrt = CASES["coulomb"]
    tr = _tangent(p, wrt[:5])
    for j, name in enumerate(wrt[:5]):
        fx, fv, same = _central(p, name, H, method="exact")
        assert same
        assert _rel(tr.dx_dp[:, j], fx) < 1e-6, name


def test_step_size_sweep_shows_truncation_then_rounding():
    """Central differences converge like h^2 until rounding takes over; the tangent sits
    at the bottom of that curve."""
    p = CASES["stribeck"][0]
    tr = _tangent(p, ("b1",))
    err = {}
    for h in (1e-2, 1e-3, 1e-4, 1e-6, 1e-10):
        fx, _, same = _central(p, "b1", h)
        err[h] = _rel(tr.dx_dp[:, 0], fx) if same else math.inf
    assert err[1e-3] < err[1e-2] / 30  # truncation, O(h^2)
    assert min(err.values()) < 1e-7
    assert err[1e-10] > 10 * min(err.values())  # rounding, O(eps / h)


def test_matches_differences_of_the_scipy_reference():
    p = OscillatorParams.preset("stribeck", u0=2.0, nu=0.5)
    t_eval = np.linspace(0.0, 15.0, 151)
    tr = simulate(p, 15.0, state=OscillatorState.start(p, x0=X0, v0=V0), wrt=("b1", "xfs"),
                  rtol=RTOL)
    for j, name in enumerate(("b1", "xfs")):
        h = 1e-5
        xa = reference_solution(p.replace(**{name: getattr(p, name) + h}), 15.0, X0, V0,
                                t_eval)[1]
        xb = reference_solution(p.replace(**{name: getattr(p, name) - h}), 15.0, X0, V0,
                                t_eval)[1]
        assert _rel(tr.dx_dp[:, j], (xa - xb) / (2 * h)) < 1e-5, name


def test_run_stats_derivatives_match_differences():
    p = OscillatorParams.preset("stribeck", u0=2.0, nu=0.5)
    st0 = OscillatorState.start(p, x0=X0, v0=V0)
    r = run_stats(p, T, state=st0, wrt=("b1", "xfs", "u0"), rtol=RTOL)
    assert r.wrt == ("b1", "xfs", "u0")
    plain = run_stats(p, T, state=st0, rtol=RTOL)
    assert r.vr2_integral == pytest.approx(plain.vr2_integral, rel=1e-9)
    for j, name in enumerate(r.wrt):
        a = run_stats(p.replace(**{name: getattr(p, name) + H}), T, state=st0, rtol=RTOL)
        b = run_stats(p.replace(**{name: getattr(p, name) - H}), T, state=st0, rtol=RTOL)
        for key in ("vr2_integral", "stick_time"):
            fd = (getattr(a, key) - getattr(b, key)) / (2 * H)
            assert r.derivatives[key][j] == pytest.approx(fd, rel=1e-6, abs=1e-8), (name, key)
        assert r.derivatives["x"][j] == pytest.approx((a.state.x - b.state.x) / (2 * H),
                                                      rel=1e-6, abs=1e-8)


def test_state_is_the_plain_runs():
    p, wrt = CASES["stribeck"]
    tr = _tangent(p, wrt)
    plain = simulate(p, T, state=OscillatorState.start(p, x0=X0, v0=V0), rtol=RTOL,
                     method="event")
    np.testing.assert_array_equal(tr.x, plain.x)
    np.testing.assert_array_equal(tr.event_t, plain.event_t)


def test_stick_holds_dv_at_dV():
    p = OscillatorParams(u0=1.15, nu=0.1)
    tr = _tangent(p, ("xfk", "V"))
    stuck = tr.mode == 0
    assert stuck.any()
    np.testing.assert_array_equal(tr.dv_dp[stuck, 0], 0.0)
    np.testing.assert_array_equal(tr.dv_dp[stuck, 1], 1.0)


def test_grazing_contact_is_flagged():
    """Unforced Coulomb slip below the belt whose velocity maximum just reaches V (the
    start's v0 bisected to the last bits between a miss and a crossing): the contact is
    flagged as grazing, and the derivatives are NaN from there."""
    p = OscillatorParams(lam=0.5, V=1.0, xfk=2.5, xfs=4.0, u0=0.0)
    x0 = 2.5  # at the slip's equilibrium: v then peaks at about half |v0|

    def touches(v0: float) -> bool:
        start = OscillatorState.start(p, x0=x0, v0=v0)
        return simulate(p, 8.0, state=start, method="event").n_stick > 0

    miss, hit = -1.0, -3.0
    assert not touches(miss) and touches(hit)
    for _ in range(80):
        mid = 0.5 * (miss + hit)
        miss, hit = (miss, mid) if touches(mid) else (mid, hit)
    tr = simulate(p, 8.0, state=OscillatorState.start(p, x0=x0, v0=hit), wrt=("xfk",),
                  dt_out=0.05)
    assert tr.singular.shape == (1,)
    assert tr.singular["name"][0] == "grazing"
    tc = tr.singular["t"][0]
    assert tc == pytest.approx(tr.event_t[0])
    assert np.all(np.isfinite(tr.dx_dp[tr.t < tc]))
    assert np.all(np.isnan(tr.dx_dp[tr.t > tc]))
    assert np.all(np.isnan(tr.event_t_dp))


@pytest.mark.parametrize(("wrt", "method", "match"), [
    (("mu",), "auto", "unknown parameter 'mu'"),
    (("delta",), "auto", "whole values"),
    (("lam", "lam"), "auto", "twice"),
    ((), "auto", "empty"),
    (("lam",), "exact", "method 'auto' or 'event'"),
    (("lam",), "rk4", "method 'auto' or 'event'"),
])
def test_refusals_name_the_value(wrt, method, match):
    p = OscillatorParams.preset("exponential", u0=1.0)
    with pytest.raises(ValueError, match=match):
        simulate(p, 5.0, wrt=wrt, method=method)


def test_v0_refused_from_a_stuck_start_and_strings_refused():
    p = OscillatorParams(u0=0.5)
    stuck = OscillatorState.start(p, x0=0.0, v0=1.0)
    assert stuck.mode == 0
    with pytest.raises(ValueError, match="'v0' has no derivative"):
        simulate(p, 5.0, state=stuck, wrt=("v0",))
    with pytest.raises(TypeError, match="sequence of parameter names"):
        simulate(p, 5.0, wrt="lam")


def test_without_wrt_nothing_changes():
    tr = simulate(OscillatorParams(u0=1.15, nu=0.1), 5.0)
    assert tr.wrt == () and tr.dx_dp is None and tr.stats.derivatives == {}


_LAW = st.sampled_from(["coulomb", "viscous", "stribeck", "exponential"])


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(law=_LAW, u0=st.floats(0.5, 4.0), nu=st.floats(0.2, 1.8), lam=st.floats(0.2, 0.8),
       delta=st.sampled_from([1.0, 2.0]), cv=st.sampled_from([0.0, 0.05]))
def test_property_random_plants(law, u0, nu, lam, delta, cv):
    """Over random plants of every law: where the switching sequence holds at +-h, the
    tangent agrees with central differences (of both methods for the Coulomb law)."""
    extra = {"delta": delta, "cv": cv} if law == "exponential" else {}
    p = OscillatorParams.preset(law, u0=u0, nu=nu, lam=lam, **extra)
    names = ("xfs", "lam", "u0", "eta") + (("vs",) if law == "exponential" else ())
    tr = simulate(p, 15.0, state=OscillatorState.start(p, x0=X0, v0=V0), wrt=names,
                  rtol=RTOL, dt_out=0.5)
    assume(tr.singular.shape == (0,))
    methods = ("event", "exact") if law == "coulomb" else ("event",)
    for j, name in enumerate(names):
        h = 1e-6 * max(1.0, abs(getattr(p, name)))
        for method in methods:
            a, b = (simulate(p.replace(**{name: getattr(p, name) + s * h}), 15.0, rtol=RTOL,
                             dt_out=0.5, state=OscillatorState.start(p, x0=X0, v0=V0),
                             method=method) for s in (1.0, -1.0))
            if not (a.event_kind.shape == b.event_kind.shape == tr.event_kind.shape
                    and np.all(a.event_kind == tr.event_kind)):
                continue
            fd = (a.x - b.x) / (2 * h)
            assert _rel(tr.dx_dp[:, j], fd) < 1e-5, (name, method)


def test_t_eval_gives_outputs_at_given_instants():
    p = OscillatorParams.preset("stribeck", u0=2.0, nu=0.5)
    t = np.sort(np.random.default_rng(0).uniform(0.0, 20.0, 50))
    t[0] = 0.0
    tr = simulate(p, t_eval=t, wrt=("b1",))
    np.testing.assert_array_equal(tr.t, t)
    assert tr.dx_dp.shape == (50, 1)
    whole = simulate(p, 20.0, dt_out=0.01)
    assert tr.x[-1] == pytest.approx(np.interp(t[-1], whole.t, whole.x), abs=1e-3)
    for bad, match in (([0.0, 1.0, 1.0], "must increase"), ([0.0, np.nan], "not finite"),
                       ([1.0, 2.0], r"t_eval\[0\] = 1.0"), ([0.0], "at least 2")):
        with pytest.raises(ValueError, match=match):
            simulate(p, t_eval=bad)
    with pytest.raises(ValueError, match="give one of them"):
        simulate(p, 5.0, t_eval=[0.0, 4.0])
