"""Bracketed root and extremum searches on a step's closed form or dense output.

The search itself (``_bracket_with``) is written once; it evaluates the searched function
through the evaluator it is given. Each family of functions has its own evaluator and its
own compiled searches: the closed form of a Coulomb slip step and the exact stick motion
(``_root_closed``, ``_extremum_closed``, ``_bracket_closed``), and the Taylor polynomial of
an event step (``..._dense``). A Coulomb run thus compiles no Taylor code.
"""

from typing import NamedTuple

from ..jit import kernel
from .closed_form import _slip_at, _stick_at
from .constants import EVENT_REL_TOL, EXTREMUM_REL_TOL, MAX_ROOT_ITER, TINY
from .taylor import _dense_v
from .workspace import C_SD, C_V

# What a root search evaluates.
K_SLIP_H = 0  # slip (closed form): h = sd * (v - V)
K_SLIP_V = 1  # slip (closed form): v
K_STICK_F = 2  # stick: f = -lam V - x + g
K_DENSE_H = 3  # slip (Taylor polynomial of the step): h = sd * (v - V)
K_DENSE_V = 4  # slip (Taylor polynomial of the step): v


class Bracket(NamedTuple):
    """A bracket [lo, hi] of a root of F: F at both ends (opposite signs, or ``fhi`` 0), and
    F' and F'' there (NaN if unknown), which place the search's first point."""

    lo: float
    hi: float
    flo: float
    fhi: float
    dlo: float
    dhi: float
    qlo: float
    qhi: float


@kernel
def _feval_closed(cx, kind, tau):
    """Value, first and second derivative at relative time tau of K_SLIP_H, K_SLIP_V or
    K_STICK_F."""
    if kind == K_SLIP_H:
        _, v, acc, jerk = _slip_at(cx, tau)
        sd = cx[C_SD]
        return sd * (v - cx[C_V]), sd * acc, sd * jerk
    if kind == K_SLIP_V:
        _, v, acc, jerk = _slip_at(cx, tau)
        return v, acc, jerk
    _, f, fd, fdd = _stick_at(cx, tau)
    return f, fd, fdd


@kernel
def _feval_dense(cx, kind, tau):
    """Value, first and second derivative at relative time tau of K_DENSE_H or K_DENSE_V."""
    v, dv, ddv = _dense_v(cx, tau)
    if kind == K_DENSE_H:
        sd = cx[C_SD]
        return sd * (v - cx[C_V]), sd * dv, sd * ddv
    return v, dv, ddv


@kernel
def _hermite_root(flo, fhi, dlo, dhi, qlo, qhi, H):
    """Fraction of a bracket of length H where the quintic Hermite interpolant of F (value,
    slope dlo/dhi and curvature qlo/qhi at both ends) vanishes: two Halley steps on it from
    the secant point, no evaluation of F. The interpolant is within H^6 |F^(6)| / 46080 of
    F, so on a scan step of a radian this typically lies within ~1e-5 H of the root (median
    3e-6 H on random sinusoids), close enough that one Halley step of F itself lands on it
    to rounding. Only a start: where F barely dips through 0 the two steps can land far
    off or outside (0, 1) (the caller then starts at the secant point), and the bracketed
    search stays exact either way. NaN data give NaN."""
    df = fhi - flo
    d0 = dlo * H
    d1 = dhi * H
    q0 = qlo * H * H
    q1 = qhi * H * H
    a2 = 0.5 * q0
    a3 = 10.0 * df - 6.0 * d0 - 4.0 * d1 - 1.5 * q0 + 0.5 * q1
    a4 = -15.0 * df + 8.0 * d0 + 7.0 * d1 + 1.5 * q0 - q1
    a5 = 6.0 * df - 3.0 * (d0 + d1) - 0.5 * (q0 - q1)
    s = flo / (flo - fhi)
    for _ in range(2):
        p = flo + s * (d0 + s * (a2 + s * (a3 + s * (a4 + s * a5))))
        dp = d0 + s * (2.0 * a2 + s * (3.0 * a3 + s * (4.0 * a4 + s * (5.0 * a5))))
        ddp = 2.0 * a2 + s * (6.0 * a3 + s * (12.0 * a4 + s * (20.0 * a5)))
        s = s - 2.0 * p * dp / (2.0 * dp * dp - p * ddp)
    return s


@kernel(takes_kernels=True)
def _bracket_with(feval, cx, kind, deriv, offset, br, rel_tol):
    """Shrink the :class:`Bracket` ``br`` of a root of F to rounding level; return (lo, hi).

    ``feval(cx, kind, tau)`` gives the searched function's value and first two derivatives
    (a family's evaluator: ``_feval_closed`` or ``_feval_dense``). F is ``value - offset``
    (deriv = 0) or the first derivative (deriv = 1) of ``kind``;
    ``br.flo`` and ``br.fhi`` have opposite signs or ``fhi`` is 0; F' and F'' at the ends
    (NaN if unknown) place the first point. Halley
    steps (Newton steps for a derivative's root) from the last point, kept inside the
    bracket, fall back to bisection; once a step is below half the
    tolerance the next point is placed just past the root so the bracket closes from both
    sides. The returned ``hi`` is on ``fhi``'s side of the root.
    """
    lo = br.lo
    hi = br.hi
    flo = br.flo
    fhi = br.fhi
    if fhi == 0.0:
        return hi, hi
    if flo == 0.0:
        return lo, lo
    tol = rel_tol * (abs(lo) + abs(hi)) + TINY
    # start at the root of the ends' Hermite interpolant, else at the secant point (kept
    # off the ends): a step is short against the curvature, so either is already close
    # and Halley needs few iterations (measured, self_excited: 2.5 evaluations a contact
    # search and 2.4 a stick exit's, instead of 4.2 and 4.1 from the secant point)
    frac = _hermite_root(flo, fhi, br.dlo, br.dhi, br.qlo, br.qhi, hi - lo)
    if not 0.0 < frac < 1.0:
        frac = min(0.95, max(0.05, flo / (flo - fhi)))
    t = lo + (hi - lo) * frac
    pos_lo = flo > 0.0
    for _ in range(MAX_ROOT_ITER):
        f0, f1, f2 = feval(cx, kind, t)
        if deriv == 0:
            f = f0 - offset
            df = f1
        else:
            f = f1
            df = f2
        if f == 0.0:
            return t, t
        if (f > 0.0) == pos_lo:
            lo = t
        else:
            hi = t
        if hi - lo <= tol:
            break
        tn = -1.0
        if df != 0.0:
            # Halley's step where the second derivative is known (value searches), Newton's
            # otherwise
            den = df if deriv != 0 else df - 0.5 * f * f2 / df
            tn = t - f / den
            # converged from one side: probe just across the root, half a tolerance past
            # it, so the bracket with t closes at once (a whole one often left it wider
            # than the tolerance, costing another evaluation)
            if abs(tn - t) < 0.5 * tol:
                tn = tn + (0.5 * tol if tn > t else -0.5 * tol)
        if not (lo < tn < hi):
            tn = 0.5 * (lo + hi)
        t = tn
    return lo, hi


@kernel
def _bracket_closed(cx, kind, deriv, offset, br, rel_tol):
    """``_bracket_with`` on the closed form (K_SLIP_H, K_SLIP_V, K_STICK_F)."""
    return _bracket_with(_feval_closed, cx, kind, deriv, offset, br, rel_tol)


@kernel
def _bracket_dense(cx, kind, deriv, offset, br, rel_tol):
    """``_bracket_with`` on a Taylor step's polynomial (K_DENSE_H, K_DENSE_V)."""
    return _bracket_with(_feval_dense, cx, kind, deriv, offset, br, rel_tol)


@kernel
def _root_closed(cx, kind, offset, lo, hi, flo, fhi, dlo, dhi, qlo, qhi):
    """Point of a bracket of a root of ``kind`` - offset on ``fhi``'s side (where the
    switch has happened); its derivatives at the ends as in ``_bracket_with``."""
    _, b = _bracket_closed(cx, kind, 0, offset, Bracket(lo, hi, flo, fhi, dlo, dhi, qlo, qhi),
                           EVENT_REL_TOL)
    return b


@kernel
def _root_dense(cx, kind, offset, lo, hi, flo, fhi, dlo, dhi, qlo, qhi):
    """``_root_closed`` on a Taylor step's polynomial."""
    _, b = _bracket_dense(cx, kind, 0, offset, Bracket(lo, hi, flo, fhi, dlo, dhi, qlo, qhi),
                          EVENT_REL_TOL)
    return b


@kernel
def _extremum_closed(cx, kind, lo, hi, dlo, dhi, ddlo, ddhi, dddlo, dddhi):
    """Relative time of the extremum of ``kind`` in [lo, hi], from its derivative's signs
    (``dlo``, ``dhi``), and its second and third derivatives there (NaN if unknown)."""
    a, b = _bracket_closed(cx, kind, 1, 0.0, Bracket(lo, hi, dlo, dhi, ddlo, ddhi, dddlo, dddhi),
                           EXTREMUM_REL_TOL)
    return 0.5 * (a + b)


@kernel
def _extremum_dense(cx, kind, lo, hi, dlo, dhi, ddlo, ddhi, dddlo, dddhi):
    """``_extremum_closed`` on a Taylor step's polynomial."""
    a, b = _bracket_dense(cx, kind, 1, 0.0, Bracket(lo, hi, dlo, dhi, ddlo, ddhi, dddlo, dddhi),
                          EXTREMUM_REL_TOL)
    return 0.5 * (a + b)
