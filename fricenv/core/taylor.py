"""Taylor-series slip steps of the event method, and their dense output.

The slip equation is a polynomial ODE in (x, v) plus two tones, so the Taylor
coefficients of its solution follow from a recurrence: Cauchy products for (v - V)^2 and
(v - V)^3, and the tones' derivatives cycle through cos, -sin, -cos, sin. One step costs
O(n^2) flops at order n, takes steps several times longer than a 5th-order Runge-Kutta
method at the same tolerance (~10x at rtol 1e-10), and its dense output is the series
itself, exact to the step's accuracy everywhere inside it (switches, extrema and output
times are found on it).
"""

import math

from ..friction import kernels as friction
from ..jit import kernel
from .constants import TAYLOR_EPS_FLOOR, TINY
from .slip import _step_inputs
from .trig import _INV
from .workspace import C_TL, C_TN, C_TQ, C_TV, C_TW, C_TX, C_W1, C_W2, TAYLOR_MAX_ORDER


@kernel
def taylor_order(rtol):
    """Order of the Taylor steps for a tolerance: about -ln(tol) / 2 + 1 (Jorba & Zou 2005,
    the order that minimises the work per unit time), within [6, TAYLOR_MAX_ORDER]."""
    n = int(math.ceil(1.0 - 0.5 * math.log(max(rtol, TINY))))
    return min(TAYLOR_MAX_ORDER, max(6, n))

@kernel
def _taylor_coeffs(cx, sd, x0, v0, rtol, atol):
    """Taylor coefficients of x and v at the step start (tone cos/sin in cx[C_CP1..]), to
    the order in cx[C_TN]; returns the step length at which the last two terms of the
    series fall to the tolerance (Jorba & Zou's rule, which needs no rejected steps)."""
    lam, V, xfk, law, lc, u1, u2, cp1, sp1, cp2, sp2 = _step_inputs(cx, sd)
    sxfk = sd * xfk
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    n = int(cx[C_TN])
    p1 = u1  # u_i w_i^k / k!
    p2 = u2
    xk = x0
    vk = v0
    wk = v0 - V
    cx[C_TX] = x0
    cx[C_TV] = v0
    for k in range(n):
        cx[C_TW + k] = wk
        fric = friction.taylor_term(law, lc, sd, cx, (C_TW, C_TQ, C_TL), k, wk)
        m = k & 3
        if m == 0:
            g = p1 * cp1 + p2 * cp2
        elif m == 1:
            g = -(p1 * sp1 + p2 * sp2)
        elif m == 2:
            g = -(p1 * cp1 + p2 * cp2)
        else:
            g = p1 * sp1 + p2 * sp2
        a = fric + g - lam * vk - xk
        if k == 0:
            a -= sxfk
        r = _INV[k + 1]
        xk = vk * r
        vk = a * r
        wk = vk
        cx[C_TX + k + 1] = xk
        cx[C_TV + k + 1] = vk
        p1 *= w1 * r
        p2 *= w2 * r
    cx[C_TW + n] = wk
    # (floored at rounding level: a zero target, or one below what doubles resolve, would
    # shrink the step to nothing and the run would never end)
    size = max(abs(x0), abs(v0))
    eps = max(atol + rtol * size, TAYLOR_EPS_FLOOR * max(size, 1.0))
    last = max(abs(cx[C_TX + n]), abs(cx[C_TV + n]))
    prev = max(abs(cx[C_TX + n - 1]), abs(cx[C_TV + n - 1]))
    # h = min((eps / prev)^(1 / (n - 1)), (eps / last)^(1 / n)) times a safety factor
    le = math.log(eps)
    lh = math.inf
    if prev > 0.0:
        lh = (le - math.log(prev)) * _INV[n - 1]
    if last > 0.0:
        lh = min(lh, (le - math.log(last)) * _INV[n])
    h = math.exp(lh - 0.7 * _INV[n - 1])
    return friction.taylor_step_cap(law, lc, cx, C_TL, n, eps, h)

@kernel
def _taylor_vr2(cx, tau):
    """Integral of (v - V)^2 over [0, tau] of the current Taylor step, exactly:
    tau * sum_ij z_i z_j / (i + j + 1) with z_i = w_i tau^i.

    Summed in a fixed order, without fast-math reassociation: a reassociated sum is split
    into as many partial sums as the CPU's vectors hold, so its last bit differed between
    an AVX2 and an AVX-512 machine."""
    n = int(cx[C_TN])
    z = cx[C_TQ:C_TQ + n + 1]
    s = 1.0
    for i in range(n + 1):
        z[i] = cx[C_TW + i] * s
        s *= tau
    total = 0.0
    for i in range(n + 1):
        zi = z[i]
        row = 0.5 * zi * _INV[2 * i + 1]
        for j in range(i + 1, n + 1):
            row += z[j] * _INV[i + j + 1]
        total += zi * row
    return 2.0 * tau * total

# Dense output of a Taylor slip step: the series itself, in tau from the step start
# ----------------------------------------------------------------------------------------
@kernel
def _dense_v(cx, tau):
    """v, v', v'' of the current Taylor step at relative time tau (Horner)."""
    n = int(cx[C_TN])
    p = cx[C_TV + n]
    d1 = 0.0
    d2 = 0.0
    for k in range(n - 1, -1, -1):
        d2 = d2 * tau + d1
        d1 = d1 * tau + p
        p = p * tau + cx[C_TV + k]
    return p, d1, 2.0 * d2

@kernel
def _dense_x(cx, tau):
    n = int(cx[C_TN])
    p = cx[C_TX + n]
    for k in range(n - 1, -1, -1):
        p = p * tau + cx[C_TX + k]
    return p

@kernel
def _dense_bounds(cx, L):
    """Bounds on |v''| and |v'''| over [0, L] of the current Taylor step's polynomial."""
    n = int(cx[C_TN])
    m2 = 0.0
    m3 = 0.0
    for k in range(n, 1, -1):
        ak = abs(cx[C_TV + k]) * (k * (k - 1))
        m2 = m2 * L + ak
        if k >= 3:
            m3 = m3 * L + ak * (k - 2)
    return m2, m3
