"""The two practices the identification benchmark sets beside ``fricenv.identify``.

- :func:`tanh_fit`: the grey-box practice: the friction's sign smoothed to
  ``tanh(v_r / eps)`` (no stick: the block always slips), its ODE integrated by
  ``scipy.integrate.solve_ivp`` and fitted by ``scipy.optimize.least_squares`` with
  finite-difference derivatives. The static level has no place in that model, except in
  the exponential law's Stribeck term.
- :func:`sindy_fit`: stick-segmented SINDy: velocity and acceleration by pysindy's
  smoothed finite differences, the samples near the belt speed (stick) dropped, and a
  sparse regression (pysindy's STLSQ) of ``a + x - forcing`` on ``1, v, sgn(v_r)`` and,
  for the cubic law, ``v_r^3`` over the slip samples. ``lam`` and ``b1`` follow from the
  coefficients of ``v`` and ``1`` (``-(lam - b1)`` and ``-b1 V``), ``xfk`` from that of
  ``sgn(v_r)``; the exponential law's Stribeck term is not in the library.

Both return a dict of estimates by name (NaN where the practice has no estimate).
"""

from __future__ import annotations

import math

import numpy as np

#: Smoothing speed of the tanh model, relative to the belt speed.
EPS = 0.02


def _forcing(p, t):
    return p.amp1 * np.cos(p.omega1 * t) + p.amp2 * np.cos(p.omega2 * t)


def _friction(law: str, vals: dict, vr: np.ndarray | float, eps: float) -> np.ndarray:
    s = np.tanh(np.asarray(vr) / eps)
    if law == "exponential":
        return (s * (vals["xfk"] + (vals["xfs"] - vals["xfk"])
                     * np.exp(-(np.abs(vr) / vals["vs"]) ** 2)) + vals["cv"] * vr)
    return s * vals["xfk"] - vals.get("b1", 0.0) * vr + vals.get("b3", 0.0) * vr ** 3


TANH_NAMES = {"coulomb": ("lam", "xfk"), "viscous": ("lam", "xfk", "b1"),
              "stribeck": ("lam", "xfk", "b1", "b3"),
              "exponential": ("lam", "xfk", "xfs", "vs", "cv")}


def tanh_fit(law: str, p, t: np.ndarray, x: np.ndarray, start: dict) -> dict:
    """The smoothed-friction output-error fit of ``law`` to ``(t, x)``, from ``start``
    (the law's preset values, as ``identify``'s first start)."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import least_squares

    names = (*TANH_NAMES[law], "x0", "v0")
    V = p.V

    def simulate_x(z):
        vals = dict(zip(names, z, strict=True))

        def rhs(tt, y):
            f = _friction(law, vals, y[1] - V, EPS * max(1.0, abs(V)))
            return (y[1], -vals["lam"] * y[1] - y[0] - f + _forcing(p, tt))

        sol = solve_ivp(rhs, (t[0], t[-1]), (vals["x0"], vals["v0"]), t_eval=t,
                        method="LSODA", rtol=1e-8, atol=1e-10)
        if not sol.success or sol.y.shape[1] != t.size:
            return np.full(t.size, 1e3)
        return sol.y[0]

    z0 = np.array([start[n] for n in names], dtype=float)
    lo = np.array([0.0 if n in ("lam", "xfk", "cv") else (0.05 if n == "vs" else -np.inf)
                   for n in names])
    sol = least_squares(lambda z: simulate_x(z) - x, np.maximum(z0, lo), bounds=(lo, np.inf),
                        x_scale="jac", diff_step=1e-3, max_nfev=40 * len(names))
    out = dict(zip(names, sol.x.tolist(), strict=True))
    out["converged"] = bool(sol.status > 0)
    return out


def sindy_fit(law: str, p, t: np.ndarray, x: np.ndarray) -> dict:
    """Stick-segmented SINDy on the slip samples of ``(t, x)``."""
    import pysindy as ps

    dt = float(np.median(np.diff(t)))
    fd = ps.SmoothedFiniteDifference(smoother_kws={"window_length": 15, "polyorder": 3})
    xs = fd.smoother(x, **fd.smoother_kws)
    v = fd._differentiate(xs, dt)
    a = fd._differentiate(v, dt)
    V = p.V
    vr = v - V
    slip = np.abs(vr) > 0.1 * max(1.0, abs(V))
    target = (a + xs - _forcing(p, t))[slip]
    cols = [np.ones(slip.sum()), v[slip], np.sign(vr[slip])]
    names = ["one", "v", "s"]
    if law in ("stribeck", "exponential"):
        cols.append(vr[slip] ** 3)
        names.append("vr3")
    theta = np.column_stack(cols)
    opt = ps.STLSQ(threshold=1e-3, alpha=1e-6)
    opt.fit(theta, target[:, None])
    c = dict(zip(names, opt.coef_[0].tolist(), strict=True))
    b1 = -c["one"] / V if law != "coulomb" else 0.0
    out = {"lam": -c["v"] + b1, "xfk": -c["s"], "xfs": math.nan}
    if law in ("viscous", "stribeck"):
        out["b1"] = b1
    if law == "stribeck":
        out["b3"] = -c.get("vr3", math.nan)
    if law == "exponential":  # its Stribeck term is outside the library
        out["lam"] = -c["v"] + b1  # cv enters as -b1: lam - (-cv) is what v's coefficient is
        out["cv"] = -b1
    return out
