"""Independent event-driven reference solution of the model, with SciPy's ``solve_ivp``.

Written from the model as docs/model.md states it, alone (not from ``fricenv.core``), so
that agreement with the kernels means something. Slip phases are integrated with DOP853 at
tight tolerances and terminal events on ``v - V = 0``; a second pair of events on the
acceleration locates every local extremum of ``v`` so that tangential contacts (grazing) and
double crossings hidden inside one step are not missed. Stick phases are exact (``x = x_s +
V (t - t_s)``); their end, ``|f| > x_fs``, is found by a fine scan (including interior
extrema of ``f``) and ``brentq``.

It ships with the package so that the accuracy tests and the benchmarks (``fricenv bench
solvers``, ``fricenv bench sweep``) compare against the same reference wherever fricenv is
installed. SciPy is not a dependency of fricenv: importing this module without it raises
``ImportError`` saying how to install it (``pip install scipy``, or the ``dev`` extra).

Entry points: :func:`reference_run` (the events and the phases between them, which can be
evaluated at any time) and :func:`reference_solution` (``x`` and ``v`` on a time grid).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

try:
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq
except ImportError as _exc:  # (SciPy is optional for fricenv, required here)
    raise ImportError(
        "fricenv.testing.scipy_reference needs SciPy, which fricenv does not install: "
        "pip install scipy (or pip install 'fricenv[dev]')") from _exc

EVENT_STICK = 1  # slip -> stick
EVENT_SLIP = 2  # stick -> slip
EVENT_REVERSAL = 3  # slip -> opposite slip without sticking

#: |v - V| at a local extremum of v below which the extremum counts as a contact.
GRAZE_TOL = 1e-12


@dataclass(frozen=True)
class _P:
    """Plain copy of the parameters, so the reference needs only attribute access."""

    lam: float
    V: float
    xfk: float
    xfs: float
    b1: float
    b3: float
    u1: float
    u2: float
    w1: float
    w2: float
    # the exponential Stribeck law (``exponential`` True): its speed, exponent, viscosity
    exponential: bool = False
    vs: float = 1.0
    delta: float = 1.0
    cv: float = 0.0

    @classmethod
    def of(cls, params: Any) -> _P:
        exponential = getattr(params, "friction", None) == "exponential"
        return cls(
            lam=float(params.lam), V=float(params.V), xfk=float(params.xfk),
            xfs=float(params.xfs), b1=float(params.b1), b3=float(params.b3),
            u1=float(params.amp1), u2=float(params.amp2),
            w1=float(params.omega1), w2=float(params.omega2),
            exponential=exponential,
            **({k: float(getattr(params, k)) for k in ("vs", "delta", "cv")} if exponential
               else {}),
        )

    def friction(self, vr: float, s: int) -> float:
        """The friction force in slip in direction ``s`` (the model page's laws)."""
        if self.exponential:
            return (s * (self.xfk + (self.xfs - self.xfk)
                         * math.exp(-((abs(vr) / self.vs) ** self.delta))) + self.cv * vr)
        return s * self.xfk - self.b1 * vr + self.b3 * vr**3

    def g(self, t: Any) -> Any:
        return self.u1 * np.cos(self.w1 * t) + self.u2 * np.cos(self.w2 * t)

    def dg(self, t: Any) -> Any:
        return -self.u1 * self.w1 * np.sin(self.w1 * t) - self.u2 * self.w2 * np.sin(self.w2 * t)

    def f_stick(self, t: Any, x: Any) -> Any:
        """Every force but friction, at v = V: the friction a stuck block must supply."""
        return -self.lam * self.V - x + self.g(t)

    def accel(self, t: float, x: float, v: float, s: int) -> float:
        return (-self.lam * v - x - self.friction(v - self.V, s)
                + self.u1 * math.cos(self.w1 * t) + self.u2 * math.cos(self.w2 * t))


@dataclass
class _Segment:
    t0: float
    t1: float
    mode: int
    sol: Any = None  # OdeSolution for slip
    x_s: float = 0.0  # stick: x at t0


@dataclass
class ReferenceRun:
    """Piecewise solution: evaluate anywhere in [0, t_end] with :meth:`evaluate`."""

    p: _P
    segments: list[_Segment] = field(default_factory=list)
    events: list[tuple[float, int]] = field(default_factory=list)
    n_rhs: int = 0

    def evaluate(self, t_eval: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x, v, mode at ``t_eval``; a time on a switch belongs to the later segment."""
        t_eval = np.asarray(t_eval, dtype=float)
        x = np.full(t_eval.shape, np.nan)
        v = np.full(t_eval.shape, np.nan)
        mode = np.zeros(t_eval.shape, dtype=np.int64)
        starts = np.array([s.t0 for s in self.segments])
        idx = np.clip(np.searchsorted(starts, t_eval, side="right") - 1, 0, len(starts) - 1)
        for k in np.unique(idx):
            seg = self.segments[k]
            sel = idx == k
            tt = np.clip(t_eval[sel], seg.t0, seg.t1)
            mode[sel] = seg.mode
            if seg.mode == 0:
                x[sel] = seg.x_s + self.p.V * (tt - seg.t0)
                v[sel] = self.p.V
            else:
                y = seg.sol(tt)
                x[sel] = y[0]
                v[sel] = y[1]
        return x, v, mode


def _root(fun: Any, a: float, b: float, *args: float) -> float:
    """Root of ``fun`` bracketed by [a, b], to the last bits of t."""
    return brentq(fun, a, b, args=args, xtol=1e-15, rtol=4 * np.finfo(float).eps)


def _stick_end(p: _P, t_s: float, x_s: float, t_end: float) -> float | None:
    """First time after ``t_s`` at which ``|f| > x_fs`` during stick, or None before t_end.

    Scans a grid fine enough that ``f'`` changes sign at most once per cell, checks the
    interior extremum of every cell too (a brief excursion above x_fs is not skipped),
    then refines the crossing with ``brentq``.
    """
    w_max = max(p.w1 if p.u1 else 0.0, p.w2 if p.u2 else 0.0, 1e-3)
    h = min(0.01, 0.05 / w_max)

    def f(t: float) -> float:
        return float(p.f_stick(t, x_s + p.V * (t - t_s)))

    def fp(t: float) -> float:
        return float(-p.V + p.dg(t))

    t_a = t_s
    chunk = 4096
    while t_a < t_end:
        ts = t_a + h * np.arange(chunk + 1)
        ts = ts[ts < t_end]
        ts = np.append(ts, t_end) if ts[-1] < t_end else ts
        F = p.f_stick(ts, x_s + p.V * (ts - t_s))
        Fp = -p.V + p.dg(ts)
        cand = np.flatnonzero((Fp[:-1] * Fp[1:] < 0.0) | (np.abs(F[1:]) > p.xfs))
        for k in cand:
            a, b = ts[k], ts[k + 1]
            # interior extremum of f in (a, b)?
            if Fp[k] * Fp[k + 1] < 0.0:
                te = _root(fp, a, b)
                fe = f(te)
                if abs(fe) > p.xfs:
                    c = p.xfs if fe > 0 else -p.xfs
                    return _root(lambda t, c: f(t) - c, a, te, c)
            if abs(F[k + 1]) > p.xfs:
                c = p.xfs if F[k + 1] > 0 else -p.xfs
                if (f(a) - c) * (F[k + 1] - c) > 0.0:  # already beyond at a (rounding)
                    return a
                return _root(lambda t, c: f(t) - c, a, b, c)
        t_a = ts[-1]
    return None


def _slip(p: _P, t0: float, x0: float, v0: float, s: int, t_end: float, rtol: float,
          atol: float, max_step: float) -> tuple[Any, float, float, float, bool, int]:
    """Integrate slip ``s`` from (t0, x0, v0) up to the first contact with v = V or t_end.

    Returns (dense solution, t1, x1, v1, contact?, n_rhs).
    """
    V = p.V

    def rhs(t: float, y: np.ndarray) -> list[float]:
        return [y[1], p.accel(t, y[0], y[1], s)]

    def ev_contact(t: float, y: np.ndarray) -> float:
        return y[1] - V

    # (solve_ivp reads an event's settings from attributes of the function)
    ev_contact.terminal = True  # type: ignore[attr-defined]
    ev_contact.direction = -s  # type: ignore[attr-defined]  # s=+1: v falls through V

    def ev_min(t: float, y: np.ndarray) -> float:  # a: - -> +, local minimum of v
        return p.accel(t, y[0], y[1], s)

    def ev_max(t: float, y: np.ndarray) -> float:  # a: + -> -, local maximum of v
        return p.accel(t, y[0], y[1], s)

    ev_min.direction = 1.0  # type: ignore[attr-defined]
    ev_max.direction = -1.0  # type: ignore[attr-defined]

    sol = solve_ivp(rhs, (t0, t_end), [x0, v0], method="DOP853", rtol=rtol, atol=atol,
                    events=[ev_contact, ev_min, ev_max], dense_output=True,
                    max_step=max_step)
    if sol.status < 0:
        raise RuntimeError(f"solve_ivp failed at t={sol.t[-1]}: {sol.message}")
    t_hit = sol.t_events[0][0] if len(sol.t_events[0]) else math.inf
    # extrema facing the belt speed (min of v above V, max of v below V), and the others
    toward = sol.t_events[1] if s > 0 else sol.t_events[2]
    away = sol.t_events[2] if s > 0 else sol.t_events[1]
    eps_t = 1e-12 * max(1.0, abs(t0))
    for te in toward:
        if te <= t0 + eps_t or te >= t_hit:
            continue
        vr = float(sol.sol(te)[1]) - V
        if s * vr > GRAZE_TOL:
            continue
        if s * vr >= -GRAZE_TOL:  # tangential contact (grazing)
            return sol.sol, float(te), float(sol.sol(te)[0]), V, True, sol.nfev
        # v crossed V and came back inside one step: find the first crossing
        prev = [ta for ta in away if t0 + eps_t < ta < te]
        lo = prev[-1] if prev else t0
        if s * (float(sol.sol(lo)[1]) - V) <= 0.0:  # fall back on a fine scan
            grid = np.linspace(t0, te, 2001)
            vv = sol.sol(grid)[1] - V
            i = int(np.argmax(s * vv <= 0.0))
            lo = grid[max(i - 1, 0)]
        tc = _root(lambda t: float(sol.sol(t)[1]) - V, lo, te)
        return sol.sol, tc, float(sol.sol(tc)[0]), V, True, sol.nfev
    if math.isfinite(t_hit):
        return sol.sol, float(t_hit), float(sol.y_events[0][0][0]), V, True, sol.nfev
    return sol.sol, float(sol.t[-1]), float(sol.y[0, -1]), float(sol.y[1, -1]), False, sol.nfev


def reference_run(params: Any, t_end: float, x0: float = 0.0, v0: float = 0.0, *,
                  rtol: float = 1e-12, atol: float = 1e-12, max_step: float = 0.1,
                  max_events: int = 100_000) -> ReferenceRun:
    """Solve from (0, x0, v0) to ``t_end``; returns the piecewise dense solution.

    ``max_step`` bounds DOP853's steps so that sign changes of the event functions are not
    skipped by very long steps (the phases here vary on a time scale of order 1).
    """
    p = _P.of(params)
    run = ReferenceRun(p)
    t, x, v = 0.0, float(x0), float(v0)
    if v != p.V:
        mode = 1 if v > p.V else -1
    else:
        f = float(p.f_stick(t, x))
        mode = 0 if abs(f) <= p.xfs else (1 if f > 0 else -1)
    while t < t_end:
        if len(run.events) > max_events:
            raise RuntimeError(f"more than {max_events} events before t={t}")
        if mode == 0:
            t1 = _stick_end(p, t, x, t_end)
            seg = _Segment(t, t_end if t1 is None else t1, 0, x_s=x)
            run.segments.append(seg)
            if t1 is None:
                break
            x = x + p.V * (t1 - t)
            t, v = t1, p.V
            f = float(p.f_stick(t, x))
            mode = 1 if f > 0 else -1
            run.events.append((t, EVENT_SLIP))
            continue
        sol, t1, x1, v1, contact, nfev = _slip(p, t, x, v, mode, t_end, rtol, atol, max_step)
        run.n_rhs += nfev
        run.segments.append(_Segment(t, t1, mode, sol=sol))
        t, x, v = t1, x1, v1
        if not contact:
            break
        f = float(p.f_stick(t, x))
        if abs(f) <= p.xfs:
            mode = 0
            run.events.append((t, EVENT_STICK))
        else:
            mode = 1 if f > 0 else -1
            run.events.append((t, EVENT_REVERSAL))
    return run


def reference_solution(params: Any, t_end: float, x0: float = 0.0, v0: float = 0.0,
                       t_eval: np.ndarray | None = None, **kwargs: Any
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                  list[tuple[float, int]]]:
    """(t, x, v, mode, events) at ``t_eval`` (default: step 0.1 from 0 to t_end).

    ``events`` is a list of (time, kind) with kind 1 stick, 2 slip, 3 reversal.
    Keyword arguments go to :func:`reference_run` (rtol, atol, max_step).
    """
    if t_eval is None:
        t_eval = np.linspace(0.0, t_end, int(round(t_end / 0.1)) + 1)
    t_eval = np.asarray(t_eval, dtype=float)
    run = reference_run(params, t_end, x0, v0, **kwargs)
    x, v, mode = run.evaluate(t_eval)
    return t_eval, x, v, mode, run.events
