"""Regime classifier: constructed statistics, stroboscopic periodicity, and real runs."""

from __future__ import annotations

import re
from fractions import Fraction

import numpy as np
import pytest

from fricenv.checks import check_real, real_array
from fricenv.layout import (
    N_STATS,
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_SLIP,
    ST_N_STICK,
    ST_STICK_TIME,
    ST_V_MAX,
    ST_V_MIN,
    STATUS_DIVERGED,
    STATUS_EVENT_CAP,
    STATUS_NONFINITE,
    STATUS_OK,
)
from fricenv.params import OscillatorParams
from fricenv.regimes import (
    Regime,
    classify,
    classify_stats,
    exact_rational,
    rational_denominator,
    strobe_period,
    summarize,
)
from fricenv.simulate import OscillatorState, run_stats, simulate
from fricenv.sweep import cell_statistics, regime_map


def _stats(n_stick: int = 0, stick_time: float = 0.0, n_rev: int = 0,
           v: tuple[float, float] = (0.2, 0.8), n_slip: int | None = None) -> np.ndarray:
    s = np.zeros(N_STATS)
    s[ST_DURATION] = 100.0
    s[ST_N_STICK] = n_stick
    # a stick phase entered is left again, but for the last one (the count's floor)
    s[ST_N_SLIP] = max(n_stick - 1, 0) if n_slip is None else n_slip
    s[ST_STICK_TIME] = stick_time
    s[ST_N_REVERSAL] = n_rev
    s[ST_V_MIN], s[ST_V_MAX] = v
    return s


# -- constructed statistics ---------------------------------------------------------------
def test_no_contact_is_wm1() -> None:
    assert classify_stats(_stats(), nu=0.1) == Regime.WM1
    assert classify_stats(_stats(v=(1.2, 3.0)), nu=2.3) == Regime.WM1  # slip above V


def test_reversals_without_stick_is_wm2() -> None:
    assert classify_stats(_stats(n_rev=7, v=(-3.0, 5.0)), nu=0.4) == Regime.WM2
    assert classify_stats(_stats(n_rev=1, v=(-3.0, 5.0)), nu=3.7) == Regime.WM2


@pytest.mark.parametrize(("nu", "expected"), [(0.1, Regime.SSM1), (1.0, Regime.SSM1),
                                              (1.0001, Regime.SSM2), (3.5, Regime.SSM2)])
def test_stick_slip_split_at_nu_one(nu: float, expected: Regime) -> None:
    assert classify_stats(_stats(n_stick=3, stick_time=12.0, n_rev=2), nu=nu) == expected


def test_stick_counts_even_without_a_new_stick_phase() -> None:
    # the window may start inside a stick phase and break loose, never to stick again
    assert classify_stats(_stats(n_stick=0, stick_time=40.0, n_slip=1), nu=0.5) == Regime.SSM1


def test_a_window_without_any_switch_spent_stuck_is_stuck() -> None:
    """A block that never slips (belt at rest, force below x_fs) was labelled SSM1, or
    PERIODIC_STICK_SLIP at integer nu, with n_stick = n_slip = 0."""
    for nu, q, period in ((0.5, 0, 0), (1.0, 1, 1), (2.0, 1, 1)):
        assert classify_stats(_stats(stick_time=100.0), nu=nu, q=q, period=period) == \
            Regime.STUCK
    assert Regime.STUCK.has_stick and "stuck" in Regime.STUCK.description
    # without n_slip, classify cannot tell it from a block that broke loose: as before
    assert classify(0, 100.0, 0, 0.5) == Regime.SSM1
    assert classify(0, 100.0, 0, 0.5, n_slip=0) == Regime.STUCK
    assert classify(0, 100.0, 0, 0.5, n_slip=1) == Regime.SSM1
    # a switch of any kind: not stuck all along
    for kw in ({"n_stick": 1}, {"n_rev": 1}, {"n_slip": 1}):
        assert classify_stats(_stats(stick_time=50.0, **kw), nu=0.5) != Regime.STUCK
    with pytest.raises(ValueError, match="n_slip must be finite and >= 0"):
        classify(0, 1.0, 0, 0.5, n_slip=-1.0)


def test_a_diverged_run_is_labelled_diverged_whatever_its_statistics() -> None:
    s = _stats(n_stick=2, stick_time=1.0)
    s[ST_V_MAX] = np.inf
    assert classify_stats(s, 0.3, status=STATUS_DIVERGED) == Regime.DIVERGED
    assert list(classify(1, 1.0, 0, 0.3, status=np.array([STATUS_DIVERGED, STATUS_EVENT_CAP,
                                                           STATUS_OK]))) == [
        Regime.DIVERGED, Regime.UNRESOLVED, Regime.SSM1]
    assert not Regime.DIVERGED.has_stick


def test_summary_stick_fraction_is_at_most_one() -> None:
    s = _stats(stick_time=100.0 + 2e-12)
    assert summarize(s)["stick_fraction"] == 1.0


def test_periodic_only_for_integer_nu() -> None:
    stick = _stats(n_stick=2, stick_time=5.0)
    free = _stats()
    assert classify_stats(stick, nu=2.0, q=1, period=1) == Regime.PERIODIC_STICK_SLIP
    assert classify_stats(stick, nu=2.0, q=1, period=3) == Regime.PERIODIC_STICK_SLIP
    assert classify_stats(free, nu=1.0, q=1, period=1) == Regime.PERIODIC_OSCILLATION
    assert classify_stats(_stats(n_rev=4), nu=3.0, q=1, period=2) == \
        Regime.PERIODIC_OSCILLATION
    # not locked: modulated labels even at integer nu
    assert classify_stats(stick, nu=2.0, q=1, period=0) == Regime.SSM2
    # rational but not integer: the forcing is a beat, so no periodic label
    assert classify_stats(stick, nu=0.5, q=2, period=1) == Regime.SSM1
    assert classify_stats(free, nu=1.5, q=2, period=1) == Regime.WM1


def test_failed_run_is_unresolved() -> None:
    for status in (STATUS_EVENT_CAP, STATUS_NONFINITE):
        assert classify_stats(_stats(n_stick=2, stick_time=1.0), 0.3, status=status) == \
            Regime.UNRESOLVED


def test_classify_broadcasts() -> None:
    stats = np.stack([_stats(), _stats(n_rev=3), _stats(n_stick=1, stick_time=1.0),
                      _stats(n_stick=1, stick_time=1.0)])
    nu = np.array([0.5, 0.5, 0.5, 2.5])
    out = classify_stats(stats, nu, status=np.array([STATUS_OK] * 4))
    assert out.dtype == np.int8
    assert list(out) == [Regime.WM1, Regime.WM2, Regime.SSM1, Regime.SSM2]
    grid = classify(np.zeros((3, 4)), 0.0, np.ones((3, 4)), nu[None, :])
    assert grid.shape == (3, 4) and np.all(grid == Regime.WM2)


def test_bad_inputs() -> None:
    with pytest.raises(ValueError):
        classify_stats(np.zeros(3), 0.5)
    with pytest.raises(ValueError):
        classify_stats(_stats(), np.nan)
    with pytest.raises(ValueError):
        rational_denominator(float("nan"))
    with pytest.raises(ValueError, match="same length"):
        strobe_period(np.zeros(4), np.zeros(5))
    with pytest.raises(ValueError, match="m_max must be an integer >= 1, got 0"):
        strobe_period(np.zeros(6), np.zeros(6), m_max=0)
    with pytest.raises(ValueError, match="tol must be finite and >= 0, got nan"):
        strobe_period(np.zeros(6), np.zeros(6), tol=float("nan"))


def test_integer_arguments_given_as_floats_raise_type_error() -> None:
    """Counts given as floats were silently accepted (m_max=2.0 passed as 2)."""
    with pytest.raises(TypeError, match=r"m_max must be an integer, got 2\.0 \(float\)"):
        strobe_period(np.zeros(6), np.zeros(6), m_max=2.0)
    with pytest.raises(TypeError, match=r"m_max must be an integer, got True \(bool\)"):
        strobe_period(np.zeros(6), np.zeros(6), m_max=True)
    with pytest.raises(TypeError, match=r"tol must be a real number, got '1e-6' \(str\)"):
        strobe_period(np.zeros(6), np.zeros(6), tol="1e-6")
    with pytest.raises(TypeError, match=r"q_max must be an integer, got 4\.0 \(float\)"):
        rational_denominator(0.5, q_max=4.0)
    with pytest.raises(TypeError, match=r"nu must be a real number, got None"):
        rational_denominator(None)
    with pytest.raises(TypeError, match=r"q must be an integer, got 2\.0 \(float\)"):
        exact_rational(1.5, 2.0)
    assert strobe_period(np.zeros(6), np.zeros(6), m_max=np.int64(2)) == 1  # numpy ints are
    assert rational_denominator(0.5, q_max=np.int32(4)) == 2


def test_summary() -> None:
    d = summarize(_stats(n_stick=2, stick_time=25.0, n_rev=1, v=(-1.0, 2.0)))
    assert d["stick_fraction"] == pytest.approx(0.25)
    assert (d["n_stick"], d["n_reversal"], d["v_min"], d["v_max"]) == (2, 1, -1.0, 2.0)


# -- rational frequency ratios and stroboscopic periods -----------------------------------
def test_rational_denominator() -> None:
    assert rational_denominator(0.0) == 1
    assert rational_denominator(3.0) == 1
    assert rational_denominator(0.1 * 3 * 10 / 2) == 2  # 1.5 with rounding noise
    assert rational_denominator(0.75) == 4
    assert rational_denominator(0.1) == 0  # denominator 10 > q_max = 4
    assert rational_denominator(0.1, q_max=10) == 10
    assert rational_denominator(np.sqrt(2.0)) == 0
    assert exact_rational(1.4999999999, 2) == 1.5
    assert exact_rational(0.123, 0) == 0.123


def test_strobe_period_of_constructed_sequences() -> None:
    k = np.arange(12)
    assert strobe_period(np.full(12, 2.5), np.full(12, 1.0)) == 1
    two = np.where(k % 2 == 0, 1.0, -1.0)
    assert strobe_period(two, 0.5 * two) == 2
    three = np.array([0.0, 1.0, 3.0] * 4)
    assert strobe_period(three, three) == 3
    # quasi-periodic (irrational rotation): no period up to m_max
    qp = np.cos(2 * np.pi * np.sqrt(2) * k)
    assert strobe_period(qp, np.sin(2 * np.pi * np.sqrt(2) * k)) == 0
    # within / beyond the tolerance (relative to max(1, |x|, |v|))
    noisy = 1.0 + 1e-8 * np.sin(k)
    assert strobe_period(noisy, noisy) == 1
    assert strobe_period(noisy, noisy, tol=1e-10) == 0
    # a decaying transient is not periodic
    assert strobe_period(np.exp(-k), np.exp(-k)) == 0
    # a record too short to see a period twice is never called periodic
    assert strobe_period(np.array([1.0, 2.0, 1.0]), np.array([1.0, 2.0, 1.0])) == 0
    assert strobe_period(three, three, m_max=2) == 0
    # non-finite samples never look periodic (NaN compares false with any tolerance)
    assert strobe_period(np.full(12, np.nan), np.full(12, np.nan)) == 0
    assert strobe_period(np.full(12, np.inf), np.ones(12)) == 0
    with_gap = np.full(12, 2.5)
    with_gap[5] = np.nan
    assert strobe_period(with_gap, np.ones(12)) == 0


# -- real runs through the kernel ---------------------------------------------------------
def test_classifier_on_simulated_cases() -> None:
    from fricenv.sweep import cell_statistics

    cases = [
        (dict(nu=0.1, u0=0.2), Regime.WM1),  # Fig. 4a: far from v = V
        (dict(nu=0.1, u0=2.0), Regime.SSM1),  # stick phases (README, Model: u0 = 2...8)
        (dict(nu=1.15, u0=0.7), Regime.SSM2),  # Fig. 6 as parametrised: sticks
        (dict(nu=0.1, u0=30.0), Regime.WM2),  # only reversals (README, Model: u0 >= 16)
        (dict(nu=1.0, u0=1.65, eta=0.2), Regime.PERIODIC_OSCILLATION),  # Fig. 7
        (dict(nu=2.0, u0=0.1), Regime.PERIODIC_OSCILLATION),  # pure slip, locked
    ]
    params = [OscillatorParams.preset("coulomb", **kw) for kw, _ in cases]
    labels, stats, period, status = cell_statistics(params)
    assert np.all(status == STATUS_OK)
    for (kw, want), got, st in zip(cases, labels, stats, strict=True):
        assert Regime(int(got)) == want, (kw, summarize(st))
    # Fig. 7: velocity stays below the belt speed (README, Model: amplitude ~0.68)
    assert stats[4, ST_V_MAX] < 1.0
    assert period[4] == 1 and period[5] == 1


# -- argument checks (review 18: D6, D9, preset) -------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "exc", "needle"),
    [(dict(q=1, period=1), ValueError, "q must be 0 (not tested) or the denominator"),
     (dict(q=4), ValueError, "got q = 4 for nu = 0.5"),
     (dict(q=-1), ValueError, "q must be 0"),
     (dict(n_stick=np.nan), ValueError, "n_stick must be finite and >= 0"),
     (dict(stick_time=-1.0), ValueError, "stick_time must be finite and >= 0"),
     (dict(n_reversal=np.inf), ValueError, "n_reversal must be finite"),
     (dict(period=-1), ValueError, "period must be finite and >= 0"),
     (dict(nu=-3.0), ValueError, "nu must be finite and >= 0, got -3.0"),
     (dict(nu=np.inf), ValueError, "nu must be finite"),
     (dict(nu="0.5"), TypeError, "nu must be a real number"),
     (dict(n_stick="1"), TypeError, "n_stick must be a real number"),
     (dict(n_stick=None), TypeError, "n_stick must be a real number"),
     (dict(stick_time=1j), TypeError, "stick_time must be a real number"),
     (dict(status="0"), TypeError, "status must be an integer"),
     (dict(period=1.0), TypeError, "period must be an integer"),
     (dict(q=True), TypeError, "q must be an integer"),
     (dict(n_stick=np.zeros(3), nu=np.full(4, 0.5)), ValueError, "must broadcast"),
     ],
)
def test_classify_refuses_bad_inputs(kwargs, exc, needle) -> None:
    """Each was labelled silently (q = 1 at nu = 0.5 as PERIODIC_OSCILLATION, NaN counts as
    WM1, nu < 0 as SSM1, status '0' as UNRESOLVED) or failed in numpy naming nothing."""
    args = dict(n_stick=0, stick_time=0.0, n_reversal=0, nu=0.5, q=0, period=0, status=0)
    args.update(kwargs)
    with pytest.raises(exc, match=re.escape(needle)):
        classify(**args)


def test_classify_reads_no_statistics_of_a_failed_run() -> None:
    """A run that stopped may leave NaN statistics: its label is UNRESOLVED, no error."""
    assert classify(np.nan, np.nan, np.nan, 0.5, status=STATUS_NONFINITE) == \
        Regime.UNRESOLVED
    # q consistent with nu, including rounding noise of a grid value and q = 0 (not tested)
    assert classify(0, 0.0, 0, 0.1 * 3 * 10, q=1, period=1) == Regime.PERIODIC_OSCILLATION
    assert classify(0, 0.0, 0, 0.75, q=4, period=1) == Regime.WM1
    assert classify(0, 0.0, 0, 0.5, q=0, period=1) == Regime.WM1


@pytest.mark.parametrize(
    ("call", "exc", "needle"),
    [(lambda: classify_stats(5, 0.5), ValueError, "stats must have last axis"),
     (lambda: classify_stats(None, 0.5), TypeError, "stats must be an array of real"),
     (lambda: classify_stats(["a"] * N_STATS, 0.5), TypeError, "stats must be an array"),
     (lambda: strobe_period(None, None), TypeError, "xs must be a 1-d array of real"),
     (lambda: strobe_period(5, 5), ValueError, "xs and vs must be 1-d arrays"),
     (lambda: strobe_period("abc", "abc"), TypeError, "xs must be"),
     (lambda: strobe_period(np.zeros(6), np.zeros(6) + 0j), TypeError, "vs must be"),
     (lambda: exact_rational(float("nan"), 2), ValueError, "nu must be finite, got nan"),
     (lambda: exact_rational(float("inf"), 2), ValueError, "nu must be finite, got inf"),
     (lambda: exact_rational(-0.5, 2), ValueError, "nu must be finite and >= 0"),
     (lambda: exact_rational(0.5, 10**400), ValueError, "q is too large"),
     (lambda: rational_denominator(0.5, 4, "x"), TypeError, "tol must be a real number"),
     (lambda: rational_denominator(0.5, 4, -1.0), ValueError, "tol must be finite and >= 0"),
     ],
)
def test_regime_helpers_name_bad_arguments(call, exc, needle) -> None:
    """strobe_period(None, None) returned 0 and a scalar passed; the helpers raised numpy's
    or Python's own errors (IndexError, OverflowError, ...) naming nothing."""
    with pytest.raises(exc, match=re.escape(needle)):
        call()


def test_strobe_period_with_a_huge_m_max() -> None:
    """m_max = 2**70 overflowed numba's int64; periods beyond n / 2 are never accepted."""
    assert strobe_period(np.ones(6), np.ones(6), m_max=2**70) == 1
    assert strobe_period(np.ones(2), np.ones(2), m_max=2**70) == 0


@pytest.mark.parametrize(
    ("call", "needle"),
    [(lambda: OscillatorParams(u0=10**400), "u0 must lie within +-1e+12"),
     (lambda: OscillatorParams(u0=Fraction(10**400, 3)), "u0 must lie within +-1e+12"),
     (lambda: OscillatorParams(lam=-10**5000), "lam must lie within +-1e+12"),
     (lambda: check_real("x", 10**400), "x must lie within +-1.79769e+308 (float64)"),
     (lambda: real_array([0.5, 10**400], "u0 must be an array of real numbers"),
      "u0 must be an array of real numbers, each within"),
     (lambda: strobe_period(np.ones(6), np.ones(6), tol=10**400), "tol must lie within"),
     ],
)
def test_huge_python_numbers_are_value_errors_naming_the_argument(call, needle) -> None:
    """float(10**400) raised a bare OverflowError naming nothing; the message abbreviates the
    number (str() of an int beyond 4300 digits even raises)."""
    with pytest.raises(ValueError, match=re.escape(needle)) as e:
        call()
    assert len(str(e.value)) < 250 and "e+" in str(e.value)


def test_regime_map_refuses_a_huge_int_axis() -> None:
    from fricenv.sweep import regime_map

    with pytest.raises(ValueError, match="u0 must be an array of real numbers, each within"):
        regime_map("coulomb", [10**400], [0.5])


def test_preset_law_must_be_a_string() -> None:
    """preset(5) and preset(None) raised ValueError ("unknown friction law 5")."""
    for law in (5, None, b"coulomb"):
        with pytest.raises(TypeError, match="law must be a friction law name"):
            OscillatorParams.preset(law)
    with pytest.raises(ValueError, match="law: unknown friction law 'x'"):
        OscillatorParams.preset("x")
    assert OscillatorParams.preset("Viscosity").b1 == 0.2


# -- a block that never slips ----------------------------------------------------------------
STILL = OscillatorParams(V=0.0, u0=1.0, nu=0.5)  # |g| <= 2 < x_fs: held from the start


@pytest.mark.parametrize("nu", [0.5, 1.0, 2.0])
def test_a_block_that_never_slips_is_stuck_for_at_most_its_duration(nu: float) -> None:
    """Its stick time was 251.32741228718538 for a duration of 251.32741228718348, and its
    label SSM1 (PERIODIC_STICK_SLIP at nu = 1, 2) with n_stick = n_slip = 0."""
    labels, stats, _, status = cell_statistics([STILL.replace(nu=nu)])
    s = stats[0]
    assert status[0] == STATUS_OK and labels[0] == Regime.STUCK
    # (the kernel sums the phases with rounding: a few ulps short, but never over)
    assert s[ST_DURATION] * (1 - 1e-12) <= s[ST_STICK_TIME] <= s[ST_DURATION]
    assert s[ST_N_STICK] == s[ST_N_SLIP] == s[ST_N_REVERSAL] == 0
    m = regime_map(OscillatorParams(V=0.0), [1.0], [nu], progress=False)
    assert m.labels[0, 0] == Regime.STUCK
    assert 1.0 - 1e-12 <= m.stick_fraction[0, 0] <= 1.0


def test_run_stats_stick_time_is_at_most_the_duration() -> None:
    state = OscillatorState.start(STILL)
    assert state.mode == 0
    s = run_stats(STILL, 251.32741228718348, state=state)
    assert s.stick_time <= s.duration and s.stick_fraction <= 1.0
    tr = simulate(STILL, 251.32741228718348)
    assert tr.stats.stick_time <= tr.stats.duration


def test_periodicity_settings_that_contradict_each_other_are_refused(tmp_path) -> None:
    """n_strobe < 2 m_max + 1 switched the periodicity test off for every cell, silently."""
    from fricenv import SweepSettings, atlas
    from fricenv.regimes import check_periodicity_settings

    check_periodicity_settings(4, 4, 9)  # enough samples
    check_periodicity_settings(0, 4, 2)  # the test switched off on purpose
    with pytest.raises(ValueError, match=r"n_strobe=8 .* m_max=4.* 9 samples.*q_max=0"):
        check_periodicity_settings(4, 4, 8)
    with pytest.raises(ValueError, match=r"m_max=0 tests no period while q_max=4"):
        check_periodicity_settings(4, 0, 12)
    p = OscillatorParams.preset("coulomb")
    calls = [lambda: regime_map(p, [1.0], [1.0], n_strobe=8),
             lambda: regime_map(p, [1.0], [1.0], m_max=6),  # with the default n_strobe=12
             lambda: cell_statistics([p], n_strobe=8),
             lambda: atlas(p, {"u0": [1.0]}, path=tmp_path / "a.zarr",
                           settings=SweepSettings(n_strobe=8))]
    for call in calls:
        with pytest.raises(ValueError, match=r"n_strobe=(8|12) is too few .* m_max=(4|6)"):
            call()
    assert not (tmp_path / "a.zarr").exists()  # refused before anything was written
