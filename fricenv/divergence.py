"""When a run counts as diverged: a size of motion that no plant with bounded motion reaches.

A run whose kernel reports OK may still have run away: with negative net damping (the
linear law with ``b1 > lam``, or a cubic term ``b3 < 0``) the motion grows exponentially
or blows up, and its statistics reach 1e64, 1e218 or overflow to inf while the state is
still finite. Such numbers are no result; the wrappers report them as diverged
(``layout.STATUS_DIVERGED``) instead.

The bound
---------
The *motion scale* of a plant started at ``(x0, v0)`` is the largest displacement or speed
its parameters and start set::

    scale = max(1, |x0|, |v0|, u1 + u2, xfs, |V|, lam |V|, |b1 V|, |b3| |V|^3, v_anti)

(``v_anti = sqrt((b1 - lam) / b3)``, the edge of the anti-damped band around ``v = V``
when ``b3 > 0`` and ``b1 > lam``, else 0). A run over a span ``t`` has diverged when a
statistic or its end state is NaN or infinite, or when ``|x|`` or ``|v|`` (end state or
located extrema) exceeds::

    min(DIVERGENCE_FACTOR * scale * max(1, t), MOTION_CEILING)

Why no plant with bounded motion reaches it: with ``E = (x^2 + v^2) / 2`` the spring
cancels from ``dE/dt = v (-lam v - s xfk + b1 v_r - b3 v_r^3 + g)``, which is at most
``A |v| + C`` with ``A = xfk + |b1 V| + u1 + u2``, and ``C = (27/256) b3 V^4`` when the
slip damps large speeds (``b3 > 0``, or ``b3 = 0`` and ``b1 <= lam``), or
``C = 2 k v_anti^2 + (27/32) b3 V^4 + 2 k V^2`` with ``k = b1 - lam > 0`` and ``b3 > 0``.
A stick phase moves the state at speed ``|V|``. So ``r = sqrt(x^2 + v^2)`` stays below
``r0 + (A + |V|) t + sqrt(2 C t)``: at most ``6 scale max(1, t)`` for damped slip and
``(7 + 4 sqrt(k)) scale max(1, t)``, 4e6 at ``b1 = PARAM_LIMIT``, with ``b3 > 0``. Only
plants without that guarantee (``b3 = 0`` with ``b1 > lam``, or ``b3 < 0``) cross the
limit, and they do so by growing without bound. ``MOTION_CEILING`` catches a cubic law
so weak (``b3 < 1e-170``) that its band would put the scale itself out of reach.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .layout import N_STATS, ST_V_MAX, ST_V_MIN, ST_VR2_INT, ST_X_MAX, ST_X_MIN
from .params import P_LAM, P_U1, P_U2, P_V, P_XFS, law_envelope

#: How many motion scales (times ``max(1, t)``) a run may reach before it counts as
#: diverged: 25 times the energy bound above for any plant that damps large speeds.
DIVERGENCE_FACTOR = 1e8
#: Displacement or speed beyond which any run counts as diverged: there the cubic friction
#: of a parameter-sized ``b3`` (1e12 x (1e100)^3) is beyond float64, and no plant with
#: bounded motion comes near it (its scale times DIVERGENCE_FACTOR and the longest span a
#: call may run stays below 1e70).
MOTION_CEILING = 1e100

_EXTREMA = (ST_V_MAX, ST_V_MIN, ST_X_MAX, ST_X_MIN)


def motion_scale(P: np.ndarray, x0: ArrayLike, v0: ArrayLike) -> np.ndarray:
    """The motion scale (module docstring) of parameter rows ``P`` (layout ``params.P_*``,
    last axis the parameters) started at ``(x0, v0)``; broadcasts over the rows."""
    P = np.asarray(P, dtype=np.float64)
    lam, V = P[..., P_LAM], P[..., P_V]
    _, b1, b3 = law_envelope(P)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        band = np.where((b3 > 0.0) & (b1 > lam), (b1 - lam) / np.where(b3 > 0.0, b3, 1.0), 0.0)
        terms = (np.abs(x0), np.abs(v0), P[..., P_U1] + P[..., P_U2], P[..., P_XFS],
                 np.abs(V), lam * np.abs(V), np.abs(b1 * V), np.abs(b3) * np.abs(V) ** 3,
                 np.sqrt(band))
        return np.maximum.reduce(np.broadcast_arrays(1.0, *terms))


def motion_limit(P: np.ndarray, x0: ArrayLike, v0: ArrayLike, span: ArrayLike) -> np.ndarray:
    """``min(DIVERGENCE_FACTOR * motion_scale * max(1, span), MOTION_CEILING)``: beyond it
    a run has diverged."""
    with np.errstate(over="ignore"):
        return np.minimum(DIVERGENCE_FACTOR * motion_scale(P, x0, v0) * np.maximum(1.0, span),
                          MOTION_CEILING)


def diverged(P: np.ndarray, x0: ArrayLike, v0: ArrayLike, span: ArrayLike, stats: np.ndarray,
             x_end: ArrayLike = 0.0, v_end: ArrayLike = 0.0, vr2_measured: bool = True
             ) -> np.ndarray:
    """Where runs (rows of ``P`` and ``stats``, layout ``ST_*``) have diverged: a statistic,
    ``x_end`` or ``v_end`` non-finite, or ``|x|`` or ``|v|`` beyond :func:`motion_limit`.
    ``vr2_measured=False``: the (v - V)^2 integral was skipped (NaN by design), so it is
    not read."""
    stats = np.asarray(stats, dtype=np.float64)
    read = np.ones(N_STATS, dtype=bool)
    read[ST_VR2_INT] = vr2_measured
    sizes = np.abs(np.stack(np.broadcast_arrays(
        *(stats[..., k] for k in _EXTREMA), x_end, v_end), axis=-1))
    with np.errstate(invalid="ignore"):
        finite = np.all(np.isfinite(stats[..., read]), axis=-1) & np.all(np.isfinite(sizes),
                                                                         axis=-1)
        return ~finite | (np.max(sizes, axis=-1) > motion_limit(P, x0, v0, span))


def run_diverged(P: np.ndarray, x0: float, v0: float, span: float, stats: np.ndarray,
                 x_end: float, v_end: float) -> bool:
    """:func:`diverged` for one run (``P`` one parameter vector), in a few microseconds
    when the run is ordinary: it is checked after every run, and the array version costs
    more than a short run itself. The motion scale is at least 1, so sizes within
    ``DIVERGENCE_FACTOR * max(1, span)`` never diverge."""
    st = stats.tolist()
    size = max(abs(st[ST_V_MAX]), abs(st[ST_V_MIN]), abs(st[ST_X_MAX]), abs(st[ST_X_MIN]),
               abs(float(x_end)), abs(float(v_end)))
    if size <= DIVERGENCE_FACTOR * max(1.0, span) and math.isfinite(sum(st)):
        return False
    return bool(diverged(P, x0, v0, span, stats, x_end, v_end))
