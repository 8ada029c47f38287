"""The cubic law: ``F(vr) = xfk sgn(vr) - b1 vr + b3 vr^3``.

The paper's laws (b) and (c) of Fig. 2: Coulomb plus viscosity (``b1 = 0.2``) and the
Stribeck-like law that falls, then rises with slip speed (``b1 = 0.2``, ``b3 = 0.16``).
``b1 > 0`` pumps energy into slip near the belt speed; ``b3 > 0`` damps large speeds.
Slip is polynomial in the speed, so the Taylor coefficients of the event method follow
from Cauchy products of the series of ``w = v - V``.

The numeric functions below are plain Python, which :mod:`fricenv.friction.kernels`
compiles: naming the law loads no numba.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .spec import FrictionLaw, LawParam

CODE = 1


def family_code(b1: float, b3: float, coulomb_code: float) -> float:
    """The law code of a plant of the paper's family given by ``b1`` and ``b3`` alone:
    ``coulomb_code`` where both are 0 (the cubic law then is the Coulomb law, which has a
    closed form), else this law's. The one place that decides a law from its
    coefficients: plain Python, for :func:`fricenv.friction.polynomial_law`, and compiled
    for the kernels (``kernels.polynomial_code``)."""
    return coulomb_code if b1 == 0.0 and b3 == 0.0 else float(CODE)


def _force(vr: np.ndarray, values: Mapping[str, float], xfk: float, xfs: float) -> np.ndarray:
    return xfk * np.sign(vr) - values["b1"] * vr + values["b3"] * vr**3


LAW = FrictionLaw(
    name="cubic", code=CODE,
    params=(LawParam("b1", 0.0, doc="linear (viscous) coefficient; > 0 lowers friction "
                                    "with speed"),
            LawParam("b3", 0.0, doc="cubic (Stribeck-like) coefficient")),
    closed_form=False, continuous=False,
    summary="F = xfk sgn(vr) - b1 vr + b3 vr^3",
    force=_force,
    near_belt_slope=lambda values, xfk, xfs: float(values["b1"]),
    envelope=lambda values, xfk, xfs: (xfk, values["b1"], values["b3"]),
    # the damped side, lam - b1 > 0, where slip creeps towards the belt speed at that rate
    # for as long as it lasts; anti-damped slip (b1 > lam) leaves the belt speed at once,
    # and 3 b3 vr^2 grows with the speed (stiff cubic slip is brief: the steps take it)
    stiffness=lambda values, lam, xfk, xfs: np.maximum(lam - values["b1"], 0.0),
    # b3 < 0, or b1 > lam with b3 = 0: |v - V| grows without bound
    runs_away=lambda values, lam: values["b3"] < 0.0 or (values["b3"] == 0.0
                                                         and values["b1"] > lam),
    presets={"viscous": {"b1": 0.2}, "stribeck": {"b1": 0.2, "b3": 0.16}},
)


def prepare(p0, p1, p2, xfk, xfs):
    """The law's constants inside the kernels: (b1, b3, -, -)."""
    return p0, p1, 0.0, 0.0


def add_accel(a, lc, sd, vr):
    """``a + (b1 - b3 vr^2) vr``."""
    return a + (lc[0] - lc[1] * vr * vr) * vr


def sgn_accel(a, lc, s, vr):
    """``a + b1 vr - b3 vr^3``: the speed-dependent acceleration as the paper's Eq. 7 writes
    it, for the RK4 baseline (``s = sgn(vr)``)."""
    return a + lc[0] * vr - lc[1] * vr * vr * vr


def slope(lc, sd, vr):
    """d/dvr of the speed-dependent acceleration: b1 - 3 b3 vr^2."""
    return lc[0] - 3.0 * lc[1] * vr * vr


def net_slope(lc, lam, sd, vr):
    """dv'/dv in slip: b1 - lam - 3 b3 vr^2."""
    return lc[0] - lam - 3.0 * lc[1] * vr * vr


def taylor_step_cap(lc, cx, tl, n, eps, h):
    """The law puts no bound of its own on a Taylor step: its series are polynomial in
    those of w, whose decay the step rule reads."""
    return h


def taylor_term(lc, sd, cx, at, k, wk):
    """k-th Taylor coefficient of ``b1 w - b3 w^3`` from the series of w in
    ``cx[tw:tw + k + 1]`` (``wk`` its k-th term); ``(w^2)_k`` is kept in ``cx[tq + k]``
    for the next orders."""
    tw, tq, tl = at
    b1 = lc[0]
    b3 = lc[1]
    fric = b1 * wk
    if b3 != 0.0:
        # (w^2)_k by symmetry, and (w^3)_k; two partial sums each halve the chains
        q0 = 0.0
        q1 = 0.0
        half = (k + 1) // 2
        i = 0
        while i + 1 < half:
            q0 += cx[tw + i] * cx[tw + k - i]
            q1 += cx[tw + i + 1] * cx[tw + k - i - 1]
            i += 2
        if i < half:
            q0 += cx[tw + i] * cx[tw + k - i]
        q = 2.0 * (q0 + q1)
        if k % 2 == 0:
            q += cx[tw + k // 2] * cx[tw + k // 2]
        cx[tq + k] = q
        c0 = 0.0
        c1 = 0.0
        i = 1
        while i + 1 <= k:
            c0 += cx[tq + k - i] * cx[tw + i]
            c1 += cx[tq + k - i - 1] * cx[tw + i + 1]
            i += 2
        if i <= k:
            c0 += cx[tq + k - i] * cx[tw + i]
        c = (c0 + c1) + q * cx[tw]
        fric -= b3 * c
    return fric


def tangent_series(lc, sd, cx, at, out, n):
    """Taylor coefficients (orders 0 .. n - 1) along the current slip step of what the
    forward sensitivities need, from the series of w = v - V in ``cx[tw:]``: row 0 the
    slope d/dw of the speed-dependent acceleration (b1 - 3 b3 w^2), rows 1 and 2 its
    derivatives by xfk and xfs (none), rows 3 and 4 by the law's parameters (w by b1,
    -w^3 by b3), as far as ``out`` has rows (a run that needs no b3 skips w^3)."""
    tw, tl = at  # offsets of the series of w and of the law's scratch
    b1 = lc[0]
    b3 = lc[1]
    rows = out.shape[0]
    for k in range(n):
        q = 0.0  # (w^2)_k, kept in row 2 until the end
        for i in range(k + 1):
            q += cx[tw + i] * cx[tw + k - i]
        out[2, k] = q
        out[0, k] = -3.0 * b3 * q
        out[1, k] = 0.0
        if rows > 3:
            out[3, k] = cx[tw + k]
        if rows > 4:
            c = 0.0  # (w^3)_k
            for i in range(k + 1):
                c += out[2, i] * cx[tw + k - i]
            out[4, k] = -c
        if rows > 5:
            out[5, k] = 0.0
    out[0, 0] += b1
    for k in range(n):
        out[2, k] = 0.0
