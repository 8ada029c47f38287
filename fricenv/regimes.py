"""Regime taxonomy of the paper (WM, SSM, periodic) as measurable criteria.

Everything here is a pure function of statistics measured over a *measurement window* that
starts after a transient (see :mod:`fricenv.sweep` for how the window is chosen), so the
rules can be tested on hand-made inputs.

Measured per run (window only)
------------------------------
``n_stick``      slip -> stick transitions (stick phases entered)
``n_slip``       stick -> slip transitions (optional: without it STUCK is not told apart)
``stick_time``   time spent stuck; ``stick_fraction = stick_time / duration``
``n_reversal``   slip -> opposite slip through ``v = V`` without sticking
``v_min, v_max`` exact velocity extrema
``q``            denominator of ``nu = p/q`` when ``nu`` is rational with ``q <= q_max``
                 (0: not tested). The forcing then has period ``T_c = 2 pi q / eta``.
``period``       smallest ``m <= m_max`` with ``(x, v)(t + m T_c) = (x, v)(t)`` at every
                 stroboscopic sample of the window (0: none found or not tested); see
                 :func:`strobe_period`.
``status``       kernel status (``layout.STATUS_*``); anything but OK means no regime.

Labels (:class:`Regime`), checked in this order
-----------------------------------------------
``DIVERGED``              status ``STATUS_DIVERGED``: the motion ran away (a statistic
                          non-finite, or ``|x|``, ``|v|`` beyond the bound of
                          :mod:`fricenv.divergence`), so its statistics are no result.
``UNRESOLVED``            any other status but OK: the kernel stopped (event cap,
                          non-finite state, slip too stiff).
``STUCK``                 stuck over the whole window: no switch of any kind
                          (``n_stick == n_slip == n_reversal == 0``) and ``stick_time > 0``.
                          With no switch the mode never changes, so a block stuck at any
                          instant of the window is stuck in all of it (a belt at ``V = 0``
                          holding a block whose force never exceeds ``x_fs``, or a stick
                          phase longer than the window).
``PERIODIC_STICK_SLIP``   stick phases, ``nu`` an integer (``q == 1``) and ``period >= 1``.
``PERIODIC_OSCILLATION``  no stick, ``nu`` an integer and ``period >= 1``.
``SSM1``                  stick phases (``n_stick > 0`` or ``stick_time > 0``), ``nu <= 1``.
``SSM2``                  stick phases, ``nu > 1``.
``WM1``                   no stick and no reversal: ``v - V`` keeps one sign (pure slip, no
                          contact with the belt speed). Friction is a constant force here.
``WM2``                   no stick but at least one reversal: ``v`` crosses ``V`` only in
                          direct reversals (large forcing, friction a square-wave force).

Choices where the paper is ambiguous (docs/regimes.md)
-----------------------------------------------------------------
* WM1/WM2 follow the *maps* (WM1 below the first boundary in ``u0``, WM2 beyond the
  second), not the waveform names of Fig. 4 ("angular" vs "amplitude" modulation), because
  only the map reading is a property of the friction contact. Fig. 4b (pure slip, beats at
  ``nu = 0.95``) is therefore WM1 here.
* SSM requires real stick phases; SSM1/SSM2 split at ``nu = 1`` (``nu = 1`` belongs to
  SSM1, as the paper's SSM1 "ends at" ``nu = 1``).
* "Periodic" is reserved for integer ``nu``: only then is the forcing unmodulated (its
  period is the first tone's, ``2 pi / eta``). For other rational ``nu`` the forcing itself
  is a beat, so the motion is called modulated even when it repeats with the long common
  period; that repetition is still reported in ``period``. Subharmonic locking
  (``period = m > 1``) counts as periodic.
"""

from __future__ import annotations

import math
from enum import IntEnum
from fractions import Fraction

import numpy as np

from .checks import check_finite_real, check_int, check_real, got, real_array
from .jit import kernel
from .layout import (
    N_STATS,
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_SLIP,
    ST_N_STICK,
    ST_STICK_TIME,
    ST_V_MAX,
    ST_V_MIN,
    STATUS_DIVERGED,
    STATUS_OK,
)

#: Default largest denominator of nu for which periodicity is tested.
Q_MAX = 4
#: Default largest response period, in forcing periods, that is searched.
M_MAX = 4
#: Default relative tolerance of the stroboscopic comparison.
STROBE_TOL = 1e-6


class Regime(IntEnum):
    """Regime labels; the criteria are in this module's docstring."""

    UNRESOLVED = 0
    WM1 = 1
    WM2 = 2
    SSM1 = 3
    SSM2 = 4
    PERIODIC_STICK_SLIP = 5
    PERIODIC_OSCILLATION = 6
    STUCK = 7
    DIVERGED = 8

    @property
    def description(self) -> str:
        return _DESCRIPTIONS[self]

    @property
    def has_stick(self) -> bool:
        """The block is stuck for some of the window (stick-slip, or stuck throughout)."""
        return self in (Regime.SSM1, Regime.SSM2, Regime.PERIODIC_STICK_SLIP, Regime.STUCK)


_DESCRIPTIONS = {
    Regime.UNRESOLVED: "unresolved (solver stopped: event cap, slip too stiff or non-finite "
                       "state)",
    Regime.WM1: "wave modulated 1: pure slip, no contact with v = V",
    Regime.WM2: "wave modulated 2: direct reversals through v = V, no stick",
    Regime.SSM1: "stick-slip modulated 1: stick phases, nu <= 1",
    Regime.SSM2: "stick-slip modulated 2: stick phases, nu > 1",
    Regime.PERIODIC_STICK_SLIP: "periodic stick-slip: integer nu, locked response with stick",
    Regime.PERIODIC_OSCILLATION: "periodic oscillation: integer nu, locked response, no stick",
    Regime.STUCK: "stuck: the block stayed stuck on the belt over the whole window",
    Regime.DIVERGED: "diverged: the motion ran away (negative net damping); no statistics",
}


#: Relative tolerance within which ``nu`` counts as ``p/q`` (see rational_denominator).
RATIONAL_TOL = 1e-9


def _check_nu(nu: object) -> float:
    """``nu`` as a float: ``TypeError`` unless a real number, ``ValueError`` unless finite
    and >= 0 (a frequency ratio)."""
    x = check_finite_real("nu", nu)
    if x < 0.0:
        raise ValueError(f"nu must be finite and >= 0, got {nu!r}")
    return x


def rational_denominator(nu: float, q_max: int = Q_MAX, tol: float = RATIONAL_TOL) -> int:
    """``q`` if ``nu`` equals ``p/q`` (lowest terms, ``q <= q_max``) within ``tol``, else 0.

    ``tol`` is relative to ``max(1, nu)`` so that grid values such as ``0.1 * 3`` count.
    """
    nu = _check_nu(nu)
    q_max = check_int("q_max", q_max)
    tol = check_finite_real("tol", tol)
    if tol < 0.0:
        raise ValueError(f"tol must be finite and >= 0, got {tol!r}")
    if q_max < 1:
        return 0
    frac = Fraction(nu).limit_denominator(q_max)
    if abs(float(frac) - nu) <= tol * max(1.0, nu):
        return frac.denominator
    return 0


def exact_rational(nu: float, q: int) -> float:
    """``p/q`` nearest to ``nu`` (used so a sweep's forcing is exactly periodic); ``q <= 0``
    leaves ``nu`` as it is."""
    nu = _check_nu(nu)
    if check_int("q", q) <= 0:
        return float(nu)
    try:  # a huge q: nu * q is no longer a float (OverflowError, or inf for round)
        return round(nu * q) / q
    except OverflowError:
        raise ValueError(f"q is too large for nu * q to be a float: nu = {nu!r}, "
                         f"{got(q)}") from None


#: Largest ``q_max`` for which :func:`rational_denominators` pre-tests each denominator
#: in turn (one array pass each); above it every value takes the exact path.
_PRETEST_Q_MAX = 64
#: Slack of that pre-test over the exact one, per unit of ``nu + 1``: a few units in the
#: last place, so that the rounding of ``nu * q`` never hides a value the exact test takes
#: (the pre-test also doubles ``tol``).
_PRETEST_ULPS = 2.0**-48


def rational_denominators(nu: object, q_max: int = Q_MAX, tol: float = RATIONAL_TOL
                          ) -> np.ndarray:
    """:func:`rational_denominator` of each value of the array ``nu`` (int64, same shape),
    equal to it value for value.

    A vectorised pre-test keeps the values within ``2 tol max(1, nu)`` (plus rounding) of
    some ``p/q`` with ``q <= q_max``; only those take the exact path, and every value the
    exact test accepts passes the pre-test. A grid of 10^5 values thus costs milliseconds,
    not a ``Fraction`` per value.
    """
    arr = real_array(nu, "nu must be an array of real numbers")
    q_max = check_int("q_max", q_max)
    tol = check_finite_real("tol", tol)
    if tol < 0.0:
        raise ValueError(f"tol must be finite and >= 0, got {tol!r}")
    bad = ~(np.isfinite(arr) & (arr >= 0.0))
    if bad.any():
        _check_nu(float(arr.flat[int(np.argmax(bad))]))  # (raises, naming the value)
    out = np.zeros(arr.shape, dtype=np.int64)
    if q_max < 1 or arr.size == 0:
        return out
    if q_max > _PRETEST_Q_MAX:
        near = np.ones(arr.shape, dtype=bool)
    else:
        with np.errstate(over="ignore", invalid="ignore"):
            bound = 2.0 * tol * np.maximum(1.0, arr) + (arr + 1.0) * _PRETEST_ULPS
            near = np.zeros(arr.shape, dtype=bool)
            for q in range(1, q_max + 1):
                x = arr * q
                near |= ~(np.abs(x - np.rint(x)) / q > bound)  # (NaN, from inf: kept)
    for k in np.flatnonzero(near):
        out.flat[k] = rational_denominator(float(arr.flat[k]), q_max, tol)
    return out


def exact_rationals(nu: object, q: object) -> np.ndarray:
    """:func:`exact_rational` of each pair of the arrays ``nu`` and ``q`` (same shape),
    equal to it value for value: ``round(nu q) / q`` rounds half to even and divides
    correctly rounded in numpy as in Python."""
    arr = real_array(nu, "nu must be an array of real numbers")
    qs = np.asarray(q)
    if qs.shape != arr.shape or qs.dtype.kind not in "iu":
        raise ValueError(f"q must be an integer array of nu's shape {arr.shape}, got "
                         f"dtype {qs.dtype} and shape {qs.shape}")
    bad = ~(np.isfinite(arr) & (arr >= 0.0))
    if bad.any():
        _check_nu(float(arr.flat[int(np.argmax(bad))]))
    use = qs > 0
    qf = np.where(use, qs, 1).astype(np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        out = np.where(use, np.round(arr * qf) / qf, arr)
    over = ~np.isfinite(out)
    if over.any():  # nu * q beyond float: the scalar function names it
        k = int(np.argmax(over))
        exact_rational(float(arr.flat[k]), int(qs.flat[k]))
    return out


@kernel
def _strobe_period(xs: np.ndarray, vs: np.ndarray, m_max: int, tol: float) -> int:
    n = xs.shape[0]
    scale = 1.0
    for k in range(n):
        scale = max(scale, abs(xs[k]), abs(vs[k]))
    lim = tol * scale
    for m in range(1, m_max + 1):
        # at least m comparisons, so that a full candidate period is seen twice
        if n - m < m or n - m < 2:
            return 0
        ok = True
        for k in range(m, n):
            # written as "not <=" so that a NaN sample breaks every candidate period
            if not (abs(xs[k] - xs[k - m]) <= lim and abs(vs[k] - vs[k - m]) <= lim):
                ok = False
                break
        if ok:
            return m
    return 0


def strobe_period(xs: np.ndarray, vs: np.ndarray, m_max: int = M_MAX,
                  tol: float = STROBE_TOL) -> int:
    """Smallest period ``m`` (in samples) of stroboscopic samples ``(x_k, v_k)``, or 0.

    Period ``m`` holds when ``|x_k - x_{k-m}|`` and ``|v_k - v_{k-m}|`` are at most
    ``tol * max(1, max_k |x_k|, max_k |v_k|)`` for every ``k >= m``. It is only accepted if
    the samples cover the candidate period at least twice (``n - m >= max(m, 2)``), so a
    short record cannot look periodic by accident. A non-finite sample is never periodic.
    """
    xs = real_array(xs, "xs must be a 1-d array of real numbers")
    vs = real_array(vs, "vs must be a 1-d array of real numbers")
    if xs.shape != vs.shape or xs.ndim != 1:  # (a scalar is no record of samples)
        raise ValueError(
            f"xs and vs must be 1-d arrays of the same length, got shapes {xs.shape} and "
            f"{vs.shape}"
        )
    m_max = check_int("m_max", m_max, 1)  # TypeError for 2.0 (was taken as 2)
    tol = check_real("tol", tol)
    if not (math.isfinite(tol) and tol >= 0.0):
        raise ValueError(f"tol must be finite and >= 0, got {tol!r}")
    # periods beyond n / 2 are never accepted: clamping keeps a huge m_max (2**70) from
    # overflowing numba's int64 without changing any result
    return int(_strobe_period(np.ascontiguousarray(xs), np.ascontiguousarray(vs),
                              min(m_max, xs.size), tol))


def check_periodicity_settings(q_max: int, m_max: int, n_strobe: int) -> None:
    """Refuse periodicity settings that contradict each other (``ValueError`` naming the
    values).

    :func:`strobe_period` accepts a period ``m`` only when the samples cover it twice
    (``n - m >= m``) and the sweeps take ``n_strobe`` samples, so any ``n_strobe <
    2 m_max + 1`` cannot confirm every period ``<= m_max`` and the sweeps used to switch
    the whole test off: every integer-nu cell lost its PERIODIC label, in silence
    (``n_strobe=8``, or ``m_max=6`` with the default ``n_strobe=12``). ``q_max=0`` is the
    way to switch the test off; it takes no samples and needs no period.
    """
    if q_max < 1:
        return
    if m_max < 1:
        raise ValueError(f"m_max={m_max} tests no period while q_max={q_max} asks for the "
                         "periodicity test; set m_max >= 1, or q_max=0 to switch it off")
    need = 2 * m_max + 1
    if n_strobe < need:
        raise ValueError(
            f"n_strobe={n_strobe} is too few stroboscopic samples for m_max={m_max}: a "
            f"period of m_max samples is only confirmed by 2*m_max+1 = {need} samples. Raise "
            f"n_strobe to {need}, lower m_max to {max((n_strobe - 1) // 2, 0)}, or set "
            "q_max=0 to switch the periodicity test off")


def _int_array(name: str, value: object) -> np.ndarray:
    """``value`` as an int64 array: ``TypeError`` naming ``name`` unless made of integers
    (a float 1.0 or a string '0' would otherwise compare as a code)."""
    real_array(value, f"{name} must be an integer or an array of integers")  # TypeErrors
    a = np.asarray(value)
    if a.dtype.kind not in "iu":
        raise TypeError(f"{name} must be an integer or an array of integers (int64), "
                        f"{got(value)}")
    return a.astype(np.int64)


def _check_denominators(nu: np.ndarray, q: np.ndarray) -> None:
    """``ValueError`` unless each ``q`` is 0 (not tested) or the denominator of ``nu``, as
    :func:`rational_denominator` finds it: a ``q = 1`` at ``nu = 0.5`` would call a beat
    "periodic". Vectorised; the exact test runs only where the fast one fails (huge
    ``nu * q``), so a sweep's own ``q`` never costs more than a few array operations."""
    qf = np.where(q > 0, q, 1).astype(np.float64)
    p = np.round(nu * qf)
    with np.errstate(invalid="ignore"):
        ok = ((q == 0) | ((q > 0) & (np.abs(p / qf - nu) <= RATIONAL_TOL * np.maximum(1.0, nu))
                          & (np.gcd(np.where(np.abs(p) < 2.0**62, p, 1).astype(np.int64),
                                    q) == 1)))
    for k in np.flatnonzero(~ok):
        n, d = float(nu.flat[k]), int(q.flat[k])
        if d < 0 or (d > 0 and rational_denominator(n, d) != d):
            raise ValueError(f"q must be 0 (not tested) or the denominator of nu = p/q in "
                             f"lowest terms, got q = {d} for nu = {n!r}")


def classify(n_stick: np.ndarray | float, stick_time: np.ndarray | float,
             n_reversal: np.ndarray | float, nu: np.ndarray | float,
             q: np.ndarray | int = 0, period: np.ndarray | int = 0,
             status: np.ndarray | int = STATUS_OK,
             n_slip: np.ndarray | float | None = None) -> np.ndarray:
    """Regime label(s) from window statistics (broadcasting; returns int8 array or scalar).

    The rules are listed in the module docstring. ``q`` is the tested denominator of ``nu``
    (0: not tested) and ``period`` the stroboscopic period found (0: none). ``n_slip``
    (stick -> slip switches) tells a block stuck all along (STUCK) from one that broke
    loose once; without it (None) such windows are labelled as stick-slip. Inputs are
    checked first (``TypeError``/``ValueError`` naming the argument): ``nu`` finite and
    >= 0, ``q`` consistent with it, integer ``q``/``period``/``status``, and, where
    ``status`` is OK, finite non-negative counts, times and periods (a failed run's
    statistics are not read: its label is UNRESOLVED, or DIVERGED for STATUS_DIVERGED).
    """
    names = ("n_stick", "stick_time", "n_reversal", "nu", "n_slip")
    arrays = [real_array(a, f"{k} must be a real number or an array of real numbers")
              for k, a in zip(names, (n_stick, stick_time, n_reversal, nu,
                                      0.0 if n_slip is None else n_slip), strict=True)]
    arrays += [_int_array(k, a) for k, a in (("q", q), ("period", period), ("status", status))]
    try:
        n_stick, stick_time, n_reversal, nu, slips, q, period, status = np.broadcast_arrays(
            *arrays)
    except ValueError:
        shapes = ", ".join(f"{k} {a.shape}" for k, a in zip(
            (*names, "q", "period", "status"), arrays, strict=True) if k != "n_slip"
            or n_slip is not None)
        raise ValueError(f"the arguments must broadcast to one shape, got {shapes}") from None
    if not np.all(np.isfinite(nu)) or np.any(nu < 0.0):
        bad = float(nu[~(np.isfinite(nu) & (nu >= 0.0))].flat[0])
        raise ValueError(f"nu must be finite and >= 0, got {bad!r}")
    _check_denominators(nu, q)
    ok = status == STATUS_OK
    for k, a in (("n_stick", n_stick), ("stick_time", stick_time), ("n_reversal", n_reversal),
                 ("n_slip", slips), ("period", period)):
        bad = ok & ~(np.isfinite(a) & (a >= 0))
        if np.any(bad):
            raise ValueError(f"{k} must be finite and >= 0 where status is OK, got "
                             f"{a[bad].flat[0].item()!r}")
    stick = (n_stick > 0) | (stick_time > 0)
    periodic = (q == 1) & (period >= 1)
    out = np.where(n_reversal > 0, Regime.WM2, Regime.WM1).astype(np.int8)
    out = np.where(stick, np.where(nu <= 1.0, Regime.SSM1, Regime.SSM2), out)
    out = np.where(periodic & stick, Regime.PERIODIC_STICK_SLIP, out)
    out = np.where(periodic & ~stick, Regime.PERIODIC_OSCILLATION, out)
    if n_slip is not None:  # no switch at all: the mode seen stuck is the whole window's
        out = np.where((n_stick == 0) & (slips == 0) & (n_reversal == 0) & (stick_time > 0),
                       Regime.STUCK, out)
    out = np.where(status != STATUS_OK, Regime.UNRESOLVED, out)
    out = np.where(status == STATUS_DIVERGED, Regime.DIVERGED, out).astype(np.int8)
    return out if out.ndim else out[()]


def classify_stats(stats: np.ndarray, nu: np.ndarray | float, q: np.ndarray | int = 0,
                   period: np.ndarray | int = 0,
                   status: np.ndarray | int = STATUS_OK) -> np.ndarray:
    """:func:`classify` on statistics arrays of layout ``ST_*`` (last axis ``N_STATS``)."""
    stats = real_array(stats, "stats must be an array of real numbers (layout ST_*)")
    if stats.ndim < 1 or stats.shape[-1] != N_STATS:
        raise ValueError(f"stats must have last axis {N_STATS}, got shape {stats.shape}")
    return classify(stats[..., ST_N_STICK], stats[..., ST_STICK_TIME],
                    stats[..., ST_N_REVERSAL], nu, q, period, status, stats[..., ST_N_SLIP])


def summarize(stats: np.ndarray) -> dict[str, float]:
    """Readable dict of one window's statistics (for reports and debugging)."""
    s = np.asarray(stats, dtype=float)
    dur = s[ST_DURATION]
    return {
        "duration": float(dur),
        # (at most 1: a run stuck throughout may sum its stick time a few ulps long)
        "stick_fraction": float(min(s[ST_STICK_TIME] / dur, 1.0)) if dur > 0 else math.nan,
        "n_stick": int(s[ST_N_STICK]),
        "n_slip": int(s[ST_N_SLIP]),
        "n_reversal": int(s[ST_N_REVERSAL]),
        "v_min": float(s[ST_V_MIN]),
        "v_max": float(s[ST_V_MAX]),
    }
