"""Friction identification and excitation design (fricenv.identification).

The fits are checked on records simulated from known plants: the truth must lie within
the reported intervals, the law must be recognised, a record that cannot determine a
parameter must say so, and the Fisher information from the exact Jacobian must match one
from central differences of the simulator.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from clirun import run
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fricenv import OscillatorParams, simulate
from fricenv.identification import (
    DEFAULT_EXCITATION,
    design_excitation,
    identify,
    simulate_record,
)
from fricenv.identification.design import fisher_information, marginal_covariance
from fricenv.identification.model import start_state

ETA = 0.6
PERIOD = 2 * math.pi / ETA
#: A rich excitation: the block slips on both sides of the belt and breaks away on both.
RICH = {"u0": 4.0, "nu": 1.7, "eta": ETA}
KNOWN_RICH = {"eta": ETA, "nu": 1.7, "u0": 4.0, "V": 1.0}


def _record(law: str, seed: int, periods: float = 10, snr_db: float = 30, **over):
    p = OscillatorParams.preset(law, **(RICH | over))
    rec = simulate_record(p, periods * PERIOD, snr_db=snr_db, rng=np.random.default_rng(seed))
    return p, rec


def test_coulomb_fit_recovers_the_truth_within_its_intervals():
    p, rec = _record("coulomb", 1)
    res = identify(rec["t"], rec["x"], known=KNOWN_RICH, laws=("coulomb",))
    fit = res.fits["coulomb"]
    assert res.best == "coulomb" and fit.converged, fit.message
    for name in ("lam", "xfk", "xfs"):
        lo, hi = res.ci[name]
        assert lo < getattr(p, name) < hi, (name, res.ci[name])
        assert hi - lo < 0.05 * getattr(p, name)  # sharp at 30 dB on this excitation
    assert fit.undetermined == {}
    # the fitted stick/slip sequence is that of the truth
    truth = simulate(p, state=start_state(p, 0.0, 0.3, 1.4), t_eval=rec["t"])
    assert abs(fit.events.size - truth.event_t.size) <= 1
    # residuals are the noise: their spread is the noise level that was added
    assert fit.sigma["x"] == pytest.approx(rec["sigma_x"], rel=0.1)


def test_the_fits_run_on_one_blas_thread(monkeypatch):
    """least_squares factors the record's Jacobian at every iteration; with several BLAS
    threads on a busy machine each small SVD took 37 ms instead of 0.14 ms."""
    import importlib

    from threadpoolctl import threadpool_info

    from fricenv.identification.threads import one_blas_thread

    identify_module = importlib.import_module("fricenv.identification.identify")

    def blas_threads() -> set[int]:
        return {lib["num_threads"] for lib in threadpool_info()
                if lib["user_api"] == "blas"}

    before = blas_threads()
    with one_blas_thread():
        assert blas_threads() == {1}
    assert blas_threads() == before  # the caller's setting comes back
    seen = []
    real = identify_module.fit_law

    def spy(*args, **kwargs):
        seen.append(blas_threads())
        return real(*args, **kwargs)

    monkeypatch.setattr(identify_module, "fit_law", spy)
    _, rec = _record("coulomb", 2, periods=3)
    identify(rec["t"], rec["x"], known=KNOWN_RICH, laws=("coulomb",))
    assert seen == [{1}]
    assert blas_threads() == before


def test_model_selection_names_the_stribeck_law():
    p, rec = _record("stribeck", 2)
    res = identify(rec["t"], rec["x"], known=KNOWN_RICH)
    assert res.best == "stribeck"
    assert set(res.fits) == {"coulomb", "viscous", "stribeck", "exponential"}
    assert res.fits["stribeck"].bic < min(f.bic for law, f in res.fits.items()
                                          if law != "stribeck") - 10
    for name in ("lam", "xfk", "xfs", "b1", "b3"):
        lo, hi = res.ci[name]
        assert lo < getattr(p, name) < hi, (name, res.ci[name])
    assert isinstance(res.params, OscillatorParams) and res.params.b3 > 0
    text = res.summary()
    assert "best law: stribeck" in text and "BIC" in text
    assert res.plot() is not None


def test_velocity_channel_is_used_and_sharpens_the_fit():
    p = OscillatorParams.preset("viscous", **RICH)
    rec = simulate_record(p, 10 * PERIOD, snr_db=30, rng=np.random.default_rng(2), with_v=True)
    known = KNOWN_RICH
    with_v = identify(rec["t"], rec["x"], v=rec["v"], known=known, laws=("viscous",))
    without = identify(rec["t"], rec["x"], known=known, laws=("viscous",))
    assert set(with_v.fit.sigma) == {"x", "v"}
    assert with_v.fit.se["b1"] < without.fit.se["b1"]
    lo, hi = with_v.ci["b1"]
    assert lo < p.b1 < hi


def test_record_that_never_sticks_flags_xfs():
    # belt far faster than the block ever moves: it slips below the belt throughout
    p = OscillatorParams(u0=1.0, nu=1.7, eta=ETA, V=6.0)
    rec = simulate_record(p, 10 * PERIOD, snr_db=30, rng=np.random.default_rng(4),
                          start=(-2.5, 0.0))
    assert rec["x_true"] is not None
    res = identify(rec["t"], rec["x"], known={"eta": ETA, "nu": 1.7, "u0": 1.0, "V": 6.0},
                   laws=("coulomb",))
    fit = res.fits["coulomb"]
    assert "xfs" in fit.undetermined and "never sticks" in fit.undetermined["xfs"]
    assert math.isinf(fit.se["xfs"]) and math.isinf(res.ci["xfs"][1])
    assert "xfs" in res.summary()


def test_low_excitation_names_lam_minus_b1():
    p = OscillatorParams.preset("viscous", b1=0.25, **DEFAULT_EXCITATION)
    rec = simulate_record(p, 20 * PERIOD, snr_db=30, rng=np.random.default_rng(5))
    known = {"eta": 0.6, "nu": DEFAULT_EXCITATION["nu"], "u0": DEFAULT_EXCITATION["u0"],
             "V": 1.0}
    res = identify(rec["t"], rec["x"], known=known, laws=("viscous",))
    fit = res.fit
    assert {"lam", "b1"} <= set(fit.undetermined)
    combo = next(c for c in fit.combinations if set(c["coefficients"]) == {"lam", "b1"})
    assert combo["name"] in ("lam - b1", "b1 - lam")
    sign = 1.0 if combo["name"] == "lam - b1" else -1.0
    assert abs(combo["value"] - sign * (p.lam - p.b1)) < 3 * combo["se"]
    # the parts' intervals are wide (tens of percent), as the record cannot separate them
    assert res.ci["lam"][1] - res.ci["lam"][0] > 0.2


def test_fisher_from_exact_jacobian_matches_finite_differences():
    p = OscillatorParams.preset("stribeck", **RICH)
    wrt = ("lam", "xfk", "xfs", "b1", "b3")
    duration, dt = 3 * PERIOD, 0.1
    F, sigma = fisher_information(p, duration, wrt=wrt, dt=dt)
    t = np.arange(0.0, duration + 0.5 * dt, dt)

    def x_of(q: OscillatorParams, x0: float = 0.3, v0: float = 1.4) -> np.ndarray:
        return simulate(q, state=start_state(q, 0.0, x0, v0), t_eval=t, rtol=1e-12).x

    cols = []
    for name in wrt:
        h = 1e-6 * max(1.0, abs(getattr(p, name)))
        up, dn = (x_of(p.replace(**{name: getattr(p, name) + s * h})) for s in (1, -1))
        cols.append((up - dn) / (2 * h))
    for name, val in (("x0", 0.3), ("v0", 1.4)):
        h = 1e-6
        kw = {"x0": 0.3, "v0": 1.4}
        up = x_of(p, **(kw | {name: val + h}))
        dn = x_of(p, **(kw | {name: val - h}))
        cols.append((up - dn) / (2 * h))
    J = np.column_stack(cols)
    F_fd = J.T @ J / sigma**2
    crlb = np.sqrt(np.diag(marginal_covariance(F, len(wrt))))
    crlb_fd = np.sqrt(np.diag(marginal_covariance(F_fd, len(wrt))))
    np.testing.assert_allclose(crlb, crlb_fd, rtol=1e-4)


def test_design_beats_the_default_excitation():
    prior = OscillatorParams(b1=0.25, b3=0.12)
    d = design_excitation(prior, duration=10 * PERIOD,
                          bounds={"u0": (0.5, 5.0), "nu": (0.1, 2.0), "eta": (0.3, 1.2)},
                          n_candidates=12)
    assert 0.5 <= d.u0 <= 5.0 and 0.1 <= d.nu <= 2.0 and 0.3 <= d.eta <= 1.2
    assert set(d.crlb) == {"lam", "xfk", "xfs", "b1", "b3"}
    assert d.volume_ratio(DEFAULT_EXCITATION) > 10.0
    assert d.regime["slips_above_belt"]
    a = design_excitation(prior, duration=10 * PERIOD, bounds={"u0": (0.5, 5.0)},
                          criterion="A", n_candidates=6)
    assert a.settings.keys() == {"u0"} and a.nu == prior.nu
    assert a.u1 == a.u2 == a.u0
    e = design_excitation(prior, duration=10 * PERIOD, bounds={"u1": (0.5, 5.0),
                                                               "u2": (0.0, 3.0)},
                          criterion="E", n_candidates=6)
    assert 0.5 <= e.u1 <= 5.0 and 0.0 <= e.u2 <= 3.0
    # E maximises the smallest eigenvalue of the relative information: no worse than the
    # default two-tone forcing on that score
    assert e.value >= design_excitation(prior, duration=10 * PERIOD,
                                        bounds={"u1": (1.5, 1.5), "u2": (1.5, 1.5)},
                                        criterion="E", n_candidates=1).value


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"t": [0.0, 1.0, math.nan]}, r"t\[2\] = nan is not finite"),
    ({"x": "inf"}, r"x\[5\] = inf is not finite"),
    ({"t": "repeat"}, r"t must increase: t\[4\]"),
    ({"t": "short"}, "shorter than one forcing period"),
    ({"known": {"eta": 0.6, "u0": 1.0, "V": 1.0}}, "missing nu"),
    ({"known": {"eta": 0.6, "nu": 1.0, "V": 1.0}}, r"missing u0 \(or both u1 and u2\)"),
    ({"known": {"eta": 0.6, "nu": 1.0, "u0": 1.0, "V": 1.0, "lam": 0.5}},
     "'lam' is estimated, not a setting"),
    ({"known": {"eta": 0.6, "nu": 1.0, "u0": 1.0, "V": 1.0, "mass": 2}},
     "'mass' is not a setting"),
    ({"known": {"eta": -0.6, "nu": 1.0, "u0": 1.0, "V": 1.0}}, "eta must be > 0"),
    ({"laws": ("lugre",)}, "unknown friction law 'lugre'"),
])
def test_bad_input_is_refused_naming_the_value(kwargs, match):
    t = np.arange(0.0, 3 * PERIOD, 0.1)
    x = np.sin(t)
    args = {"t": t, "x": x, "known": KNOWN_RICH, "laws": ("coulomb",)}
    if kwargs.get("t") == "repeat":
        t = t.copy()
        t[4] = t[3]
        kwargs = {"t": t}
    elif kwargs.get("t") == "short":
        kwargs = {"t": t[:50], "x": x[:50]}
    elif kwargs.get("t") is not None and len(kwargs["t"]) == 3:
        t = t.copy()
        t[2] = math.nan
        kwargs = {"t": t}
    elif kwargs.get("x") == "inf":
        x = x.copy()
        x[5] = math.inf
        kwargs = {"x": x}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        identify(args.pop("t"), args.pop("x"), **args)


@pytest.mark.parametrize(("bounds", "match"), [
    ({"u0": (-1.0, 2.0)}, r"u0 must be >= 0, got low = -1.0"),
    ({"eta": (0.0, 1.0)}, r"eta must be > 0"),
    ({"nu": (2.0, 1.0)}, "low <= high"),
    ({"lam": (0.1, 1.0)}, "'lam' is not a forcing setting"),
    ({"u0": (0.5, 2.0), "u1": (0.5, 2.0)}, "u0 .* or u1 and u2, not both"),
])
def test_design_refuses_bad_bounds(bounds, match):
    with pytest.raises(ValueError, match=match):
        design_excitation(OscillatorParams(), duration=20.0, bounds=bounds)


def test_a_fit_that_did_not_converge_says_so():
    p, rec = _record("coulomb", 6)
    res = identify(rec["t"], rec["x"], known=KNOWN_RICH, laws=("coulomb",), max_nfev=1,
                   n_starts=1)
    assert not res.converged
    assert res.fit.message.startswith("did not converge")
    assert "did not converge" in res.summary()


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 199), st.sampled_from([math.nan, math.inf, -math.inf]))
def test_any_non_finite_sample_is_named(i, bad):
    t = np.arange(0.0, 2 * PERIOD, 0.05)[:200]
    x = np.zeros(t.size)
    x[i] = bad
    with pytest.raises(ValueError, match=rf"x\[{i}\] = {bad!r} is not finite"):
        identify(t, x, known=KNOWN_RICH)


def test_cli_identify_writes_a_report(tmp_path, capsys):
    p, rec = _record("coulomb", 7)
    path = tmp_path / "record.csv"
    np.savetxt(path, np.column_stack([rec["t"], rec["x"]]), delimiter=",", header="t,x",
               comments="")
    out = tmp_path / "report"
    code, stdout, stderr = run(capsys, "identify", str(path), "--known",
                               "eta=0.6,nu=1.7,u0=4,V=1", "--laws", "coulomb", "viscous",
                               "--out", str(out))
    assert code == 0, stderr
    assert "best law: coulomb" in stdout
    report = (out / "report.md").read_text()
    assert "| coulomb |" in report and "identification.png" in report
    assert (out / "identification.png").stat().st_size > 1000
    code, _, stderr = run(capsys, "identify", str(path), "--known", "eta=0.6,u0=4,V=1")
    assert code == 2 and "missing nu" in stderr


def test_cli_design_prints_the_design(capsys):
    code, stdout, stderr = run(capsys, "design", "--law", "viscous", "--duration", "60",
                               "--bounds", "u0=0.5:4,nu=0.2:2", "--no-plot")
    assert code == 0, stderr
    assert "D-optimal" in stdout and "b1" in stdout and "default" in stdout
    code, _, stderr = run(capsys, "design", "--duration", "60", "--bounds", "u0=-1:2")
    assert code == 2 and "u0 must be >= 0" in stderr
