"""Statistics of a slip step: extrema of v and x, and the (v - V)^2 integral."""

import math

from ..jit import kernel
from ..layout import ST_VR2_INT, ST_X_MAX, ST_X_MIN
from .closed_form import _slip_at
from .constants import EXTREMUM_REL_TOL, REACH_SLACK
from .roots import K_DENSE_V, K_SLIP_V, Bracket, _bracket_closed, _bracket_dense
from .state import _note_v, _note_x
from .taylor import _dense_x
from .workspace import C_V, C_XA, W_SKIP_EXTREMA, W_SKIP_VR2

NAN = math.nan


@kernel
def _x_turn_closed(cx, piece):
    """x where v of the closed-form slip step changes sign in ``piece`` (see
    ``_x_extrema_between``)."""
    t = _bracket_closed(cx, K_SLIP_V, 0, 0.0, piece, EXTREMUM_REL_TOL)[1]
    x, _, _, _ = _slip_at(cx, t)
    return x


@kernel
def _x_turn_dense(cx, piece):
    """x where v of the current Taylor step changes sign in ``piece`` (see
    ``_x_extrema_between``)."""
    t = _bracket_dense(cx, K_DENSE_V, 0, 0.0, piece, EXTREMUM_REL_TOL)[1]
    return _dense_x(cx, t)


@kernel(takes_kernels=True)
def _x_extrema_between(x_turn, cx, stats, piece, vabs):
    """Displacement extremum where v changes sign on a monotone piece of v: ``piece`` is
    the :class:`~fricenv.core.roots.Bracket` [lo, hi] with v at its ends, ``x_turn``
    (``_x_turn_closed`` or ``_x_turn_dense``, the step's family) finds x there.

    ``vabs`` bounds |v| over the whole step, so |x - x(0)| <= vabs * hi: when that cannot
    reach past the recorded extrema the search is skipped (it matters once the motion
    has decayed to rounding noise, where v flips sign every step).
    """
    if piece.flo * piece.fhi < 0.0:
        x0 = cx[C_XA]
        reach = vabs * piece.hi * REACH_SLACK
        if x0 + reach <= stats[ST_X_MAX] and x0 - reach >= stats[ST_X_MIN]:
            return
        _note_x(stats, x_turn(cx, piece))


@kernel(takes_kernels=True)
def _slip_extrema(x_turn, cx, stats, tau_e, t_ext, v_ext, v0, v1, x1):
    """Extrema of v and x over a slip step [0, tau_e] (t_ext: v's interior extremum;
    ``x_turn`` as in ``_x_extrema_between``)."""
    _note_v(stats, v1)
    _note_x(stats, x1)
    if cx[W_SKIP_EXTREMA] == 1.0:
        pass
    elif 0.0 <= t_ext <= tau_e:
        _note_v(stats, v_ext)
        vabs = max(abs(v0), abs(v_ext), abs(v1))
        # (the pieces with v at their ends; v' and v'' there are not needed)
        _x_extrema_between(x_turn, cx, stats, Bracket(0.0, t_ext, v0, v_ext, NAN, NAN, NAN,
                                                      NAN), vabs)
        _x_extrema_between(x_turn, cx, stats, Bracket(t_ext, tau_e, v_ext, v1, NAN, NAN, NAN,
                                                      NAN), vabs)
    else:
        _x_extrema_between(x_turn, cx, stats, Bracket(0.0, tau_e, v0, v1, NAN, NAN, NAN, NAN),
                           max(abs(v0), abs(v1)))

@kernel(called_once=True)
def _slip_stats(cx, stats, tau_e, ext, p0, p1, v_mid):
    """Extrema and the (v - V)^2 integral over a closed-form slip step [0, tau_e] (the
    event method's steps have their own: ``_slip_extrema`` and the series' integral).

    ``p0``, ``p1``: the states at both ends (``closed_form.Point``: v, v', v'' are read,
    and x at the end); ``ext``: v's interior extremum (``exact.Extremum``: its time, < 0
    if none, and v); v at the midpoint ``v_mid`` unless NaN.
    """
    _slip_extrema(_x_turn_closed, cx, stats, tau_e, ext.t, ext.v, p0.v, p1.v, p1.x)
    if cx[W_SKIP_VR2] == 1.0:
        return
    # Hermite quadrature of y = (v - V)^2 from y, y', y'' at both ends and, if given, y at
    # the midpoint: exact for degree 7 (5 without the midpoint). y' = 2 (v - V) a and
    # y'' = 2 (a^2 + (v - V) j), with a = v', j = v''.
    V = cx[C_V]
    a0 = p0.acc
    j0 = p0.jerk
    a1 = p1.acc
    j1 = p1.jerk
    r0 = p0.v - V
    r1 = p1.v - V
    dy0 = 2.0 * r0 * a0
    dy1 = 2.0 * r1 * a1
    ddy0 = 2.0 * (a0 * a0 + r0 * j0)
    ddy1 = 2.0 * (a1 * a1 + r1 * j1)
    if math.isnan(v_mid):
        stats[ST_VR2_INT] += tau_e * (0.5 * (r0 * r0 + r1 * r1) + tau_e * (
            0.1 * (dy0 - dy1) + tau_e * (ddy0 + ddy1) / 120.0))
    else:
        rm = v_mid - V
        stats[ST_VR2_INT] += tau_e * ((19.0 / 70.0) * (r0 * r0 + r1 * r1) + (16.0 / 35.0) * rm * rm
                                      + tau_e * ((1.0 / 35.0) * (dy0 - dy1)
                                                 + tau_e * (ddy0 + ddy1) / 840.0))

@kernel
def _vr2_from_values(h, r0, r1, mean):
    """Integral of r^2 over a step of length h from r = v - V at both ends and its mean
    (from the displacement): exact for r quadratic in time.

    For Rosenbrock steps, where v' and v'' from the equation of motion are useless: in a
    stiff stretch they carry the state's rounding times |df/dv| and its square, which in
    ``_slip_stats``' Hermite rule make the integral wrong by up to several times itself.
    The mean's own error telescopes: it is the displacement's error at the step's ends.
    """
    d = mean - 0.5 * (r0 + r1)  # r = r0 (1 - s) + r1 s + 6 d s (1 - s), s in [0, 1]
    return h * ((r0 * r0 + r0 * r1 + r1 * r1) / 3.0 + d * (r0 + r1) + 1.2 * d * d)
