"""Textbook closed forms of one Coulomb slip phase, written case by case in plain numpy.

``x'' + lam x' + x = -s xfk + u1 cos(w1 t) + u2 cos(w2 t)`` from ``x(t0) = x0``,
``x'(t0) = v0`` (docs/model.md, "Closed form in slip"). Every damping case is
its own function, with no shared clever trick, so that a bug in the solver's unified
formula cannot be mirrored here. The excitation is in absolute time (phase 0 at t = 0), as
in the model.
"""

from __future__ import annotations

import math

import numpy as np


def _particular(t: np.ndarray, s: int, xfk: float, lam: float,
                tones: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """x_p and x_p' for a sum of tones (u, w); a tone with lam = 0, w = 1 is resonant."""
    xp = np.full_like(t, -s * xfk, dtype=float)
    vp = np.zeros_like(t, dtype=float)
    for u, w in tones:
        if u == 0.0:
            continue
        if lam == 0.0 and w == 1.0:
            # x'' + x = u cos t  ->  x_p = (u/2) t sin t
            xp += 0.5 * u * t * np.sin(t)
            vp += 0.5 * u * (np.sin(t) + t * np.cos(t))
            continue
        amp = u / math.sqrt((1.0 - w * w) ** 2 + (lam * w) ** 2)
        th = math.atan2(lam * w, 1.0 - w * w)
        xp += amp * np.cos(w * t - th)
        vp += -amp * w * np.sin(w * t - th)
    return xp, vp


def underdamped(t: np.ndarray, lam: float, y0: float, yp0: float, t0: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """Homogeneous solution for lam < 2: e^{-lam tau/2} (c1 cos p tau + c2 sin p tau)."""
    p = math.sqrt(1.0 - lam * lam / 4.0)
    tau = t - t0
    c1 = y0
    c2 = (yp0 + 0.5 * lam * y0) / p
    e = np.exp(-0.5 * lam * tau)
    cs, sn = np.cos(p * tau), np.sin(p * tau)
    y = e * (c1 * cs + c2 * sn)
    yp = e * ((-0.5 * lam * c1 + p * c2) * cs + (-0.5 * lam * c2 - p * c1) * sn)
    return y, yp


def critical(t: np.ndarray, y0: float, yp0: float, t0: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """Homogeneous solution for lam = 2: (c1 + c2 tau) e^{-tau}."""
    tau = t - t0
    c1 = y0
    c2 = yp0 + y0
    e = np.exp(-tau)
    y = (c1 + c2 * tau) * e
    yp = (c2 - c1 - c2 * tau) * e
    return y, yp


def overdamped(t: np.ndarray, lam: float, y0: float, yp0: float, t0: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Homogeneous solution for lam > 2: c1 e^{r1 tau} + c2 e^{r2 tau}, r1,2 real < 0."""
    d = math.sqrt(lam * lam - 4.0)
    r1 = 0.5 * (-lam + d)
    r2 = 0.5 * (-lam - d)
    tau = t - t0
    c1 = (yp0 - r2 * y0) / (r1 - r2)
    c2 = y0 - c1
    e1, e2 = np.exp(r1 * tau), np.exp(r2 * tau)
    return c1 * e1 + c2 * e2, c1 * r1 * e1 + c2 * r2 * e2


def undamped(t: np.ndarray, y0: float, yp0: float, t0: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """Homogeneous solution for lam = 0: c1 cos tau + c2 sin tau."""
    tau = t - t0
    return y0 * np.cos(tau) + yp0 * np.sin(tau), -y0 * np.sin(tau) + yp0 * np.cos(tau)


def slip_phase(t: np.ndarray, *, s: int, x0: float, v0: float, t0: float, lam: float,
               xfk: float, u1: float, w1: float, u2: float, w2: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """x(t), v(t) of one Coulomb slip phase with direction ``s`` (no switching)."""
    t = np.asarray(t, dtype=float)
    tones = [(u1, w1), (u2, w2)]
    xp0, vp0 = _particular(np.array([t0]), s, xfk, lam, tones)
    y0 = x0 - float(xp0[0])
    yp0 = v0 - float(vp0[0])
    if lam == 0.0:
        yh, yph = undamped(t, y0, yp0, t0)
    elif lam < 2.0:
        yh, yph = underdamped(t, lam, y0, yp0, t0)
    elif lam == 2.0:
        yh, yph = critical(t, y0, yp0, t0)
    else:
        yh, yph = overdamped(t, lam, y0, yp0, t0)
    xp, vp = _particular(t, s, xfk, lam, tones)
    return xp + yh, vp + yph


def slip_phase_params(t: np.ndarray, params, *, s: int, x0: float, v0: float,
                      t0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """:func:`slip_phase` with the coefficients taken from an ``OscillatorParams``."""
    if not (params.b1 == 0.0 and params.b3 == 0.0):
        raise ValueError("closed forms hold for the Coulomb law only (b1 = b3 = 0)")
    return slip_phase(t, s=s, x0=x0, v0=v0, t0=t0, lam=params.lam, xfk=params.xfk,
                      u1=params.amp1, w1=params.omega1, u2=params.amp2, w2=params.omega2)
