"""The baseline of ``fricenv bench solvers`` that smooths friction: classical RK4 with
``sgn(v_r)`` replaced by ``tanh(v_r / eps)``. It cannot hold a stick phase and is stiff
near ``v_r = 0``, which is what the benchmark shows. Kept apart so that the benchmark's
``--help`` loads no numba."""

from __future__ import annotations

import math

import numba
import numpy as np

from fricenv.jit import THREADING_LAYER  # noqa: F401  (TBB, cache key, layer: before numba runs)


@numba.njit(cache=True)
def _tanh_accel(t: float, x: float, v: float, p: np.ndarray, eps: float) -> float:
    lam, V, xfk, b1, b3, u1, u2, w1, w2 = p
    vr = v - V
    return (-lam * v - x - xfk * math.tanh(vr / eps) + b1 * vr - b3 * vr * vr * vr
            + u1 * math.cos(w1 * t) + u2 * math.cos(w2 * t))


@numba.njit(cache=True)
def _tanh_rk4(p: np.ndarray, x0: float, v0: float, dt: float, stride: int, n_out: int,
              eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Classical RK4 with a fixed step; output every ``stride`` steps."""
    xs = np.empty(n_out)
    vs = np.empty(n_out)
    x, v, t = x0, v0, 0.0
    xs[0], vs[0] = x, v
    n = 0
    for k in range(1, n_out):
        for _ in range(stride):
            k1x, k1v = v, _tanh_accel(t, x, v, p, eps)
            k2x = v + 0.5 * dt * k1v
            k2v = _tanh_accel(t + 0.5 * dt, x + 0.5 * dt * k1x, k2x, p, eps)
            k3x = v + 0.5 * dt * k2v
            k3v = _tanh_accel(t + 0.5 * dt, x + 0.5 * dt * k2x, k3x, p, eps)
            k4x = v + dt * k3v
            k4v = _tanh_accel(t + dt, x + dt * k3x, k4x, p, eps)
            x += dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
            v += dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
            n += 1
            t = n * dt  # no drift from summing dt
        xs[k], vs[k] = x, v
    return xs, vs


