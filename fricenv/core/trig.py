"""Phases: wrapping to [0, 2 pi), cos/sin by series, rotations kept on the unit circle."""

import math

import numpy as np

from ..jit import kernel
from .constants import TWO_PI
from .workspace import TAYLOR_MAX_ORDER


@kernel
def _wrap(phi):
    if 0.0 <= phi < TWO_PI:
        return phi
    phi = phi - TWO_PI * math.floor(phi / TWO_PI)
    return phi if phi < TWO_PI else 0.0

# Taylor coefficients (-1)^k / (2k)! and (-1)^k / (2k+1)!, as products (no divisions).
_C2, _C4, _C6, _C8 = -1.0 / 2.0, 1.0 / 24.0, -1.0 / 720.0, 1.0 / 40320.0
_C10, _C12, _C14 = -1.0 / 3628800.0, 1.0 / 479001600.0, -1.0 / 87178291200.0
_C16, _C18 = 1.0 / 20922789888000.0, -1.0 / 6402373705728000.0
_S3, _S5, _S7, _S9 = -1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362880.0
_S11, _S13, _S15 = -1.0 / 39916800.0, 1.0 / 6227020800.0, -1.0 / 1307674368000.0
_S17, _S19 = 1.0 / 355687428096000.0, -1.0 / 121645100408832000.0

@kernel
def _sincos(t):
    """cos and sin of t: a Taylor series for |t| <= 1 (error < 1e-18), libm beyond.

    Scan steps keep phase advances within a radian, so the closed form's rotations and
    root searches make no libm calls, which otherwise dominate an environment step.
    """
    if abs(t) > 1.0:
        return math.cos(t), math.sin(t)
    # Estrin's scheme (pairs of terms joined by z^2, z^4, z^8) for all but the leading
    # term, added last: the same polynomials as Horner's rule with half its chain of
    # dependent operations, which root searches wait on.
    z = t * t
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    pc = ((_C2 + _C4 * z) + (_C6 + _C8 * z) * z2) + ((_C10 + _C12 * z) + (_C14 + _C16 * z)
                                                     * z2) * z4 + _C18 * z8
    ps = ((_S3 + _S5 * z) + (_S7 + _S9 * z) * z2) + ((_S11 + _S13 * z) + (_S15 + _S17 * z)
                                                     * z2) * z4 + _S19 * z8
    c = 1.0 + z * pc
    s = t + (t * z) * ps
    return c, s

@kernel
def _sincos_long(t):
    """cos and sin of |t| <= 8 by halving into ``_sincos``'s series and doubling back
    (a few ulps); libm beyond."""
    if not abs(t) <= 8.0:
        return math.cos(t), math.sin(t)
    k = 0
    while abs(t) > 1.0:
        t *= 0.5
        k += 1
    c, s = _sincos(t)
    for _ in range(k):
        c, s = c * c - s * s, 2.0 * s * c
    return c, s

@kernel
def _renorm(c, s):
    k = 1.5 - 0.5 * (c * c + s * s)
    return c * k, s * k

# 1 / k, k = 0 .. 2 TAYLOR_MAX_ORDER + 1 (no divisions in the recurrence and quadrature)
_INV = np.array([0.0] + [1.0 / k for k in range(1, 2 * TAYLOR_MAX_ORDER + 2)])
