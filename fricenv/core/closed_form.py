"""Closed form of a Coulomb slip step, and the exact stick motion.

Each slip phase of the Coulomb law is linear: its solution is the homogeneous transition
matrix (any damping) applied to the distance from the particular response to the two tones.
"""

import math
from typing import NamedTuple

from ..jit import kernel
from .constants import HOMOG_SERIES_MAX
from .state import Tones
from .trig import _sincos
from .workspace import (
    C_C1A,
    C_C2A,
    C_DV,
    C_DX,
    C_KC1,
    C_KC2,
    C_KS1,
    C_KS2,
    C_LAM,
    C_P2,
    C_RES1,
    C_RES2,
    C_S1A,
    C_S2A,
    C_SD,
    C_U1,
    C_U2,
    C_V,
    C_VA,
    C_W1,
    C_W2,
    C_XA,
    C_XFK,
)


class Point(NamedTuple):
    """The closed-form slip state at one instant: x, v, v', v'' and the tones' cos/sin."""

    x: float
    v: float
    acc: float
    jerk: float
    tones: Tones


# Closed form of a Coulomb slip step
# ----------------------------------------------------------------------------------------
@kernel
def _homog(tau, lam, p2):
    """Transition matrix of x'' + lam x' + x = 0 over tau, for every damping.

    With p^2 = 1 - lam^2/4, C = cos(p tau) and S = sin(p tau)/p are entire in p^2, so one
    formula covers under-, critically and over-damped motion; near p^2 tau^2 = 0 a series
    avoids dividing by p, and in the over-damped case the two real exponentials are
    formed directly so nothing overflows.
    """
    z = p2 * tau * tau
    if abs(z) < HOMOG_SERIES_MAX:
        c = 1.0 - z / 2.0 * (1.0 - z / 12.0 * (1.0 - z / 30.0 * (1.0 - z / 56.0 * (
            1.0 - z / 90.0 * (1.0 - z / 132.0)))))
        s = tau * (1.0 - z / 6.0 * (1.0 - z / 20.0 * (1.0 - z / 42.0 * (1.0 - z / 72.0 * (
            1.0 - z / 110.0 * (1.0 - z / 156.0))))))
        e = math.exp(-0.5 * lam * tau)
        ec = e * c
        es = e * s
    elif p2 > 0.0:
        p = math.sqrt(p2)
        e = math.exp(-0.5 * lam * tau)
        c, sn = _sincos(p * tau)
        ec = e * c
        es = e * sn / p
    else:
        q = math.sqrt(-p2)
        slow = math.exp(-tau / (0.5 * lam + q))  # rate lam/2 - q, written without cancelling
        fast = math.exp(-(0.5 * lam + q) * tau)
        ec = 0.5 * (slow + fast)
        es = 0.5 * (slow - fast) / q
    return ec + 0.5 * lam * es, es, -es, ec - 0.5 * lam * es

@kernel
def _particular(cx, tau, c1, s1, c2, s2, sd):
    """Particular solution (x_p, v_p) at relative time tau, tone phases (c_i, s_i) there."""
    xp = -sd * cx[C_XFK]
    vp = 0.0
    if cx[C_U1] != 0.0:
        if cx[C_RES1] != 0.0:
            xp += 0.5 * cx[C_U1] * tau * s1
            vp += 0.5 * cx[C_U1] * (s1 + tau * c1)
        else:
            xp += cx[C_KC1] * c1 + cx[C_KS1] * s1
            vp += cx[C_W1] * (cx[C_KS1] * c1 - cx[C_KC1] * s1)
    if cx[C_U2] != 0.0:
        if cx[C_RES2] != 0.0:
            xp += 0.5 * cx[C_U2] * tau * s2
            vp += 0.5 * cx[C_U2] * (s2 + tau * c2)
        else:
            xp += cx[C_KC2] * c2 + cx[C_KS2] * s2
            vp += cx[C_W2] * (cx[C_KS2] * c2 - cx[C_KC2] * s2)
    return xp, vp

@kernel
def _slip_start(cx, x, v, tones, sd):
    """Start a closed-form slip step at (x, v) in direction ``sd``, the tones' cos/sin
    ``tones``."""
    c1, s1, c2, s2 = tones
    cx[C_XA] = x
    cx[C_VA] = v
    cx[C_C1A] = c1
    cx[C_S1A] = s1
    cx[C_C2A] = c2
    cx[C_S2A] = s2
    cx[C_SD] = sd
    xp, vp = _particular(cx, 0.0, c1, s1, c2, s2, sd)
    cx[C_DX] = x - xp
    cx[C_DV] = v - vp

@kernel
def _rotate(cx, cr1, sr1, cr2, sr2):
    """Tone phases at the step start advanced by the rotations (cr_i, sr_i)."""
    c1 = cx[C_C1A] * cr1 - cx[C_S1A] * sr1
    s1 = cx[C_S1A] * cr1 + cx[C_C1A] * sr1
    c2 = cx[C_C2A] * cr2 - cx[C_S2A] * sr2
    s2 = cx[C_S2A] * cr2 + cx[C_C2A] * sr2
    return c1, s1, c2, s2

@kernel
def _rotate_by(cx, tau):
    """Tone phases at the step start advanced by tau (both tones)."""
    cr1, sr1 = _sincos(cx[C_W1] * tau)
    cr2, sr2 = _sincos(cx[C_W2] * tau)
    return _rotate(cx, cr1, sr1, cr2, sr2)

@kernel
def _forcing(cx, c1, s1, c2, s2):
    """g, g' and g'' for tone phases (c_i, s_i)."""
    u1 = cx[C_U1]
    u2 = cx[C_U2]
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    g = u1 * c1 + u2 * c2
    gd = -u1 * w1 * s1 - u2 * w2 * s2
    gdd = -u1 * w1 * w1 * c1 - u2 * w2 * w2 * c2
    return g, gd, gdd

@kernel
def _slip_with(cx, tau, h, tones):
    """Closed-form slip state at relative time tau: x, v, acceleration and jerk, from the
    homogeneous transition over tau ``h`` (``_homog``'s 4-tuple) and the tones' cos/sin
    there."""
    c1, s1, c2, s2 = tones
    sd = cx[C_SD]
    xp, vp = _particular(cx, tau, c1, s1, c2, s2, sd)
    x = xp + h[0] * cx[C_DX] + h[1] * cx[C_DV]
    v = vp + h[2] * cx[C_DX] + h[3] * cx[C_DV]
    g, gd, _ = _forcing(cx, c1, s1, c2, s2)
    acc = -cx[C_LAM] * v - x - sd * cx[C_XFK] + g
    jerk = -cx[C_LAM] * acc - v + gd
    return x, v, acc, jerk

@kernel
def _slip_at(cx, tau):
    """Closed-form slip state at relative time tau: x, v, acceleration and jerk."""
    p = _slip_and_phases_at(cx, tau)
    return p.x, p.v, p.acc, p.jerk

@kernel
def _slip_and_phases_at(cx, tau):
    """``_slip_at`` plus the tones' cos/sin there (a switch needs both), as a
    :class:`Point`."""
    h = _homog(tau, cx[C_LAM], cx[C_P2])
    c1, s1, c2, s2 = _rotate_by(cx, tau)
    tones = Tones(c1, s1, c2, s2)
    x, v, acc, jerk = _slip_with(cx, tau, h, tones)
    return Point(x, v, acc, jerk, tones)

@kernel
def _slip_mid_and_end(cx, tau):
    """v at tau / 2 and the state at tau (a :class:`Point`), from one evaluation at tau / 2:
    the transition over tau is its square and the rotations are doubled (a few ulps), so
    a step whose (v - V)^2 quadrature needs its midpoint pays for one evaluation, not two."""
    hm = 0.5 * tau
    m11, m12, m21, m22 = _homog(hm, cx[C_LAM], cx[C_P2])
    cm1, sm1 = _sincos(cx[C_W1] * hm)
    cm2, sm2 = _sincos(cx[C_W2] * hm)
    mc1, ms1, mc2, ms2 = _rotate(cx, cm1, sm1, cm2, sm2)
    _, v_mid, _, _ = _slip_with(cx, hm, (m11, m12, m21, m22), Tones(mc1, ms1, mc2, ms2))
    c1, s1, c2, s2 = _rotate(cx, cm1 * cm1 - sm1 * sm1, 2.0 * sm1 * cm1, cm2 * cm2 - sm2 * sm2,
                             2.0 * sm2 * cm2)
    tones = Tones(c1, s1, c2, s2)
    x, v, acc, jerk = _slip_with(cx, tau, (m11 * m11 + m12 * m21, m11 * m12 + m12 * m22,
                                           m21 * m11 + m22 * m21, m21 * m12 + m22 * m22), tones)
    return v_mid, Point(x, v, acc, jerk, tones)

@kernel
def _stick_at(cx, tau):
    """Stick state at relative time tau: x and f, f', f''."""
    c1, s1, c2, s2 = _rotate_by(cx, tau)
    x = cx[C_XA] + cx[C_V] * tau
    g, gd, gdd = _forcing(cx, c1, s1, c2, s2)
    return x, -cx[C_LAM] * cx[C_V] - x + g, -cx[C_V] + gd, gdd

@kernel
def _jerk(cx, v, a, s1, s2):
    """v'' in Coulomb slip from v, v' and the tones' sines (the law adds no slope)."""
    return -cx[C_LAM] * a - v - (cx[C_U1] * cx[C_W1] * s1 + cx[C_U2] * cx[C_W2] * s2)
