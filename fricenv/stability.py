"""Stability of the response: periodic orbits with their Floquet multipliers, and the largest
Lyapunov exponent, both from the exact tangent of a run (:mod:`fricenv.core.tangent`).

The two tones share a period when their frequencies are commensurate, ``nu = p / q``:
``T = 2 pi q / eta``. A periodic response of period ``m T`` is a fixed point of the
stroboscopic (Poincare) map over ``m T``, which :func:`periodic_orbit` finds by Newton's
method on that map's exact Jacobian, the monodromy matrix. Its eigenvalues, the Floquet
multipliers, say whether the orbit is stable (all inside the unit circle). The monodromy
includes every switch's saltation; a stick phase absorbs perturbations of v, so an orbit
that sticks has a multiplier 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np

from .checks import check_finite_real, check_int, got
from .core import initial_mode
from .layout import N_STATE, S_MODE, S_V, S_X, STATUS_OK
from .params import P_W1, P_W2, OscillatorParams
from .simulate import OscillatorState, SimulationError, run_stats, simulate

#: Largest denominator q of nu = p / q that :func:`forcing_period` recognises.
MAX_DENOMINATOR = 64


def forcing_period(params: OscillatorParams) -> float:
    """The common period of the two tones, ``2 pi q / eta`` for ``nu = p / q`` (q up to
    ``MAX_DENOMINATOR``); ``2 pi / eta`` where one tone is off or constant. ``ValueError``
    naming nu when the tones are not commensurate."""
    if params.amp2 == 0.0 or params.nu == 0.0 or params.amp1 == 0.0 and params.nu > 0.0:
        w = params.omega1 if params.amp1 != 0.0 else params.omega2
        return 2.0 * math.pi / w if w > 0.0 else math.inf
    ratio = Fraction(params.nu).limit_denominator(MAX_DENOMINATOR)
    if abs(float(ratio) - params.nu) > 1e-12 * max(1.0, params.nu):
        raise ValueError(f"nu = {params.nu!r} is not a ratio p / q with q <= "
                         f"{MAX_DENOMINATOR}: the two tones have no common period; pass "
                         "period= explicitly if the response is periodic anyway")
    return 2.0 * math.pi * ratio.denominator / params.eta


@dataclass(frozen=True)
class PeriodicOrbit:
    """A periodic response: its period, a point on it at a multiple of the forcing period
    (phase 0 of both tones), the monodromy matrix d(x, v)(T) / d(x, v)(0) (rows x, v;
    saltation included) and its eigenvalues, the Floquet multipliers (largest modulus
    first)."""

    params: OscillatorParams
    period: float
    x: float
    v: float
    mode: int
    monodromy: np.ndarray
    multipliers: np.ndarray
    residual: float
    iterations: int

    @property
    def stable(self) -> bool:
        """Whether every multiplier lies inside the unit circle."""
        return bool(np.all(np.abs(self.multipliers) < 1.0))

    @property
    def lyapunov_exponent(self) -> float:
        """log |mu_max| / T: the largest Lyapunov exponent of the orbit (-inf when every
        perturbation dies within a period)."""
        m = float(np.abs(self.multipliers[0]))
        return math.log(m) / self.period if m > 0.0 else -math.inf


def _period_map(params: OscillatorParams, x: float, v: float, T: float, rtol: float
                ) -> tuple[np.ndarray, np.ndarray, int]:
    """(x, v) after T from (x, v) at phase 0, its 2x2 Jacobian, and the start's mode."""
    state = OscillatorState.start(params, x0=x, v0=v)
    stuck = state.mode == 0
    wrt = ("x0",) if stuck else ("x0", "v0")
    tr = simulate(params, T, state=state, wrt=wrt, dt_out=T, rtol=rtol)
    assert tr.singular is not None and tr.dx_dp is not None and tr.dv_dp is not None
    if tr.singular.shape[0]:
        s = tr.singular[0]
        raise SimulationError(f"the orbit has a {s['name']} at t = {s['t']:.6g}, where the "
                              "monodromy matrix does not exist")
    J = np.zeros((2, 2))
    J[0, : len(wrt)] = tr.dx_dp[-1]
    J[1, : len(wrt)] = tr.dv_dp[-1]
    return np.array([tr.x[-1], tr.v[-1]]), J, state.mode


def periodic_orbit(params: OscillatorParams, *, state: OscillatorState | None = None,
                   periods: int = 1, period: float | None = None, transient: int = 200,
                   tol: float = 1e-10, max_iter: int = 30, rtol: float = 1e-12
                   ) -> PeriodicOrbit:
    """A periodic response of ``periods`` forcing periods (``period``: the forcing period,
    by default :func:`forcing_period`), by Newton shooting on the exact monodromy matrix.

    The start is ``state`` (default: rest) carried over ``transient`` forcing periods;
    Newton's method then solves ``P(y) = y`` for the map P over ``periods`` forcing
    periods, to ``tol`` in max |P(y) - y|. A start in stick at the section is held at
    v = V, and only x is solved for. ``SimulationError`` if Newton does not converge in
    ``max_iter`` steps (no periodic orbit near the start, or one with a grazing contact).
    """
    if not isinstance(params, OscillatorParams):
        raise TypeError(f"params must be an OscillatorParams, {got(params)}")
    m = check_int("periods", periods, 1)
    T0 = forcing_period(params) if period is None else check_finite_real("period", period)
    if not T0 > 0.0 or not math.isfinite(T0):
        raise ValueError(f"the forcing has no finite period (got {T0!r}): pass period=")
    T = m * T0
    transient = check_int("transient", transient, 0)
    start = state if state is not None else OscillatorState.start(params)
    if transient:
        start = run_stats(params, transient * T0, state=start, rtol=rtol).state
    y = np.array([start.x, start.v])
    for it in range(1, check_int("max_iter", max_iter, 1) + 1):
        end, J, mode = _period_map(params, y[0], y[1], T, rtol)
        g = end - y
        residual = float(np.max(np.abs(g if mode != 0 else g[:1])))
        if residual <= tol:
            mu = np.linalg.eigvals(J)
            mu = mu[np.argsort(-np.abs(mu))]
            return PeriodicOrbit(params, T, float(y[0]), float(y[1]), int(mode), J, mu,
                                 residual, it)
        if mode == 0:  # held at v = V: solve for x alone
            y[0] -= g[0] / (J[0, 0] - 1.0)
        else:
            y -= np.linalg.solve(J - np.eye(2), g)
    raise SimulationError(f"Newton shooting did not converge in {max_iter} iterations "
                          f"(last residual {residual:.3g}): no periodic orbit of {m} "
                          "forcing period(s) near this start; try more transient periods "
                          "or another periods=")


@dataclass(frozen=True)
class LyapunovEstimate:
    """The largest Lyapunov exponent of a run and the time it was measured over (chunks
    that met a grazing contact are left out of both)."""

    exponent: float
    time: float
    state: OscillatorState


def lyapunov_exponent(params: OscillatorParams, t_span: float, *,
                      state: OscillatorState | None = None, transient: float = 0.0,
                      renorm: float | None = None, rtol: float = 1e-10,
                      atol: float = 1e-12) -> LyapunovEstimate:
    """The largest Lyapunov exponent over ``t_span`` after ``transient`` (from ``state``,
    default rest), from the exact tangent, renormalised every ``renorm`` (default: one
    period of the faster tone, at most 10)."""
    if not isinstance(params, OscillatorParams):
        raise TypeError(f"params must be an OscillatorParams, {got(params)}")
    t_span = check_finite_real("t_span", t_span)
    transient = check_finite_real("transient", transient)
    if not t_span > 0.0 or transient < 0.0:
        raise ValueError(f"t_span must be > 0 and transient >= 0, got {t_span!r}, "
                         f"{transient!r}")
    if renorm is None:
        w = max(params.omega1, params.omega2)
        renorm = min(10.0, 2.0 * math.pi / w) if w > 0.0 else 10.0
    renorm = check_finite_real("renorm", renorm)
    if not renorm > 0.0:
        raise ValueError(f"renorm must be > 0, got {renorm!r}")
    start = state if state is not None else OscillatorState.start(params)
    out, S = lyapunov_rows([params], [start], np.array([[transient, t_span, renorm]]),
                           (rtol, atol))
    return LyapunovEstimate(float(out[0, 0]), float(out[0, 1]),
                            OscillatorState.from_array(S[0]))


#: Switching events a renormalisation interval of a Lyapunov run may hold, per unit of
#: time (as ``simulate.MAX_EVENT_RATE``).
LYAPUNOV_EVENT_RATE = 1000.0


def lyapunov_of_rows(P: np.ndarray, S: np.ndarray, spans: np.ndarray,
                     tolerances: tuple[float, float]) -> np.ndarray:
    """The largest Lyapunov exponent of each parameter row of ``P`` (layout ``P_*``) from
    its state vector in ``S`` (advanced in place), with ``spans[i]`` = (transient,
    window, renormalisation interval), in parallel: ``out[i]`` = (exponent, time counted,
    status). A run that fails leaves its status there (exponent NaN) and raises nothing:
    what a sweep's cells need."""
    from .core.lyapunov import lyapunov_rows as kernel_rows
    from .core.lyapunov import worker_buffers
    from .jit import num_threads, parallel_section

    spans = np.ascontiguousarray(spans, dtype=np.float64)
    out = np.full((P.shape[0], 3), np.nan)
    if P.shape[0] == 0:
        return out
    max_events = int(LYAPUNOV_EVENT_RATE * max(1.0, float(np.max(spans[:, 2]))))
    B = worker_buffers(min(P.shape[0], num_threads()), max_events + 2)
    with parallel_section():
        kernel_rows(np.ascontiguousarray(P), S, spans,
                    (tolerances[0], tolerances[1], max_events), B, out)
    return out


def lyapunov_rows(params: Sequence[OscillatorParams], states: Sequence[OscillatorState],
                  spans: np.ndarray, tolerances: tuple[float, float]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`lyapunov_of_rows` for plants and states: ``(out, S)`` with ``S`` the final
    state vectors; ``SimulationError`` naming the first plant whose run failed."""
    P = np.array([p.to_array() for p in params])
    S = np.array([s.to_array() for s in states])
    out = lyapunov_of_rows(P, S, spans, tolerances)
    bad = np.flatnonzero(out[:, 2] != 0)
    if bad.size:
        i = int(bad[0])
        raise SimulationError(f"the Lyapunov run of plant {i} stopped with status "
                              f"{int(out[i, 2])} by t = {S[i, 0]:.6g}", int(out[i, 2]))
    return out, S


def lyapunov_of_cells(cells: Any, settings: Any, status: np.ndarray) -> np.ndarray:
    """The largest Lyapunov exponent of each cell (``cells``: a
    :class:`fricenv.cells.CellInputs`; ``settings``: its sweep's
    :class:`fricenv.SweepSettings`; typed loosely, since the sweeps import this module)
    that ran with status OK, from the same
    start (``settings.x0, v0``), transient and window (all its segments) as its regime, by
    the event method's exact tangent (:func:`fricenv.stability.lyapunov_exponent`),
    renormalised every period of the faster tone (at most 10); NaN elsewhere, and where the
    tangent's run fails."""
    out = np.full(status.shape[0], np.nan)
    ok = np.flatnonzero(status == STATUS_OK)
    if not ok.size:
        return out
    P = np.ascontiguousarray(cells.P[ok])
    S = np.zeros((ok.size, N_STATE))
    S[:, S_X] = settings.x0
    S[:, S_V] = settings.v0
    S[:, S_MODE] = [initial_mode(row, settings.x0, settings.v0, 0.0, 0.0) for row in P]
    fast = np.maximum(P[:, P_W1], P[:, P_W2])
    renorm = np.minimum(10.0, 2.0 * np.pi / np.where(fast > 0.0, fast, np.inf))
    spans = np.stack([cells.t_transient[ok], cells.t_segment[ok] * cells.n_segment[ok],
                      np.where(renorm > 0.0, renorm, 10.0)], axis=1)
    res = lyapunov_of_rows(P, S, spans, (settings.rtol, settings.atol))
    out[ok] = np.where(res[:, 2] == STATUS_OK, res[:, 0], np.nan)
    return out
