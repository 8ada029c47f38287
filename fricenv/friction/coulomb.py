"""The Coulomb law: a constant kinetic level in slip, ``F(vr) = xfk sgn(vr)``.

The paper's law (a) of Fig. 2. Slip is then linear, so the ``exact`` method's closed form
runs it. The law has no parameters of its own: ``xfk`` and ``xfs`` are every law's.

The numeric functions below are plain Python, which :mod:`fricenv.friction.kernels`
compiles: naming the law loads no numba.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .spec import FrictionLaw

CODE = 0


def _force(vr: np.ndarray, values: Mapping[str, float], xfk: float, xfs: float) -> np.ndarray:
    return xfk * np.sign(vr)


LAW = FrictionLaw(
    name="coulomb", code=CODE, params=(), closed_form=True, continuous=False,
    summary="F = xfk sgn(vr): static level xfs, kinetic level xfk",
    force=_force,
    near_belt_slope=lambda values, xfk, xfs: 0.0,
    envelope=lambda values, xfk, xfs: (xfk, 0.0, 0.0),
    stiffness=lambda values, lam, xfk, xfs: lam,
    runs_away=lambda values, lam: False,
    presets={"coulomb": {}},
)


def prepare(p0, p1, p2, xfk, xfs):
    """The law's constants inside the kernels: none."""
    return 0.0, 0.0, 0.0, 0.0


def add_accel(a, lc, sd, vr):
    """``a`` plus the law's speed-dependent part of the slip acceleration: none."""
    return a


def sgn_accel(a, lc, s, vr):
    """The RK4 baseline's speed-dependent acceleration: none."""
    return a


def slope(lc, sd, vr):
    """d/dvr of that part: 0."""
    return 0.0


def net_slope(lc, lam, sd, vr):
    """dv'/dv in slip: the damping alone."""
    return -lam


def taylor_step_cap(lc, cx, tl, n, eps, h):
    """The law puts no bound of its own on a Taylor step."""
    return h


def taylor_term(lc, sd, cx, at, k, wk):
    """k-th Taylor coefficient of the speed-dependent part: 0."""
    return 0.0


def tangent_series(lc, sd, cx, at, out, n):
    """Taylor coefficients (orders 0 .. n - 1) of the speed-dependent acceleration's
    derivatives along a slip step (see ``cubic.tangent_series``): all 0."""
    for r in range(out.shape[0]):
        for k in range(n):
            out[r, k] = 0.0
