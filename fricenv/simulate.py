"""Public simulation API: validated inputs, allocated outputs, numba kernels underneath."""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from . import calls, core, divergence, sensitivity
from .checks import check_bounded_real, check_finite_real, check_int, check_rtol, got
from .core import constants
from .friction import law_of_code
from .layout import (
    METHOD_EVENT,
    METHOD_EXACT,
    METHODS,
    N_STATS,
    S_T,
    S_V,
    S_X,
    ST_V_MAX,
    ST_V_MIN,
    ST_VR2_INT,
    ST_X_MAX,
    ST_X_MIN,
    STATUS_BUFFER_FULL,
    STATUS_DIVERGED,
    STATUS_EVENT_CAP,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_STEP_BUDGET,
    STATUS_TOO_STIFF,
)
from .params import (
    P_LAM,
    P_LAW,
    P_LAW_PARAMS,
    P_W1,
    P_W2,
    PARAM_LIMIT,
    SLIP_STIFFNESS_LIMIT,
    OscillatorParams,
    law_stiffness,
)
from .trajectory import EVENT_DTYPE as EVENT_DTYPE  # (re-exported: defined there, made here)
from .trajectory import EVENT_NAMES as EVENT_NAMES
from .trajectory import OscillatorState as OscillatorState
from .trajectory import RunStats as RunStats
from .trajectory import Trajectory as Trajectory
from .trajectory import _check_params

#: Default cap on switching events per unit of dimensionless time. A physical run switches a
#: few times per forcing period; far more means chattering (a Zeno-like accumulation).
MAX_EVENT_RATE = 1000.0
#: Most scan steps a run may need (the RK4 step count shares it). Beyond it a run takes
#: many minutes, and a fast tone or stiff damping asking for it is more likely a typo.
MAX_SCAN_STEPS = 1e9
#: Default step budget of a call (``max_steps_per_tau`` and ``max_steps`` of ``simulate``
#: and ``run_stats``): steps in each unit of dimensionless time, and in the whole call.
MAX_STEPS_PER_TAU = constants.MAX_STEPS_PER_TAU
MAX_STEPS_PER_CALL = constants.MAX_STEPS_PER_CALL
#: Most output instants ``simulate`` records: t, x, v and the mode take 33 bytes an
#: instant (330 MB at the cap, and about as many exact steps as instants); a finer grid
#: over a longer run is refused before anything is allocated (``run_stats`` keeps no
#: trajectory, and a long run can be recorded in pieces, each continuing the last).
MAX_OUTPUTS = 1e7


class SimulationError(RuntimeError):
    """A run that cannot continue or whose result is no result: event cap exceeded, slip
    too stiff, a non-finite state, or motion that diverged. ``status`` is the reason, a
    ``layout.STATUS_*`` code (``STATUS_DIVERGED``: see :mod:`fricenv.divergence`)."""

    def __init__(self, message: str, status: int = -1) -> None:
        super().__init__(message)
        self.status = status


def _positive(name: str, value: float) -> float:
    value = check_finite_real(name, value)
    if value <= 0.0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return value


def check_start(state: OscillatorState, params: OscillatorParams, t_span: float,
                span_name: str = "t_span") -> None:
    """``ValueError`` naming the field and its value for a state the kernels cannot continue
    from consistently over ``t_span`` (called ``span_name`` in the message): magnitudes
    of t, x, v and the phases beyond ``PARAM_LIMIT`` (x and v overflow the kernels as a
    parameter would: a NaN integral, status OK), a mode other than -1, 0, 1 or one that
    contradicts v (stick needs v == V exactly: the stick step holds v there and would
    report a v - V it never integrates), and a span below the spacing of float64 at
    ``state.t``, where the end time would be lost in rounding (time would stand still, or
    jump by a whole spacing). Every public entry that starts from a given state (``simulate``,
    ``run_stats``, the environments' ``set_state``) runs this one check."""
    for name in ("t", "x", "v", "phase1", "phase2"):
        check_bounded_real(f"state.{name}", getattr(state, name), PARAM_LIMIT)
    if check_int("state.mode", state.mode) not in (-1, 0, 1):
        raise ValueError(f"state.mode must be -1, 0 or 1, got {state.mode!r}")
    spacing = math.ulp(state.t)
    if t_span < spacing:
        raise ValueError(f"{span_name} = {t_span!r} is below the spacing of float64 at "
                         f"state.t = {state.t!r} ({spacing:.3g}): the run's end time would be "
                         "lost in rounding")
    if state.mode == 0 and state.v != params.V:
        raise ValueError(f"state.mode = 0 (stick) needs v == V = {params.V!r}, got "
                         f"state.v = {state.v!r}; build the state with OscillatorState.start")
    if state.mode != 0 and (state.v - params.V) * state.mode < 0.0:
        raise ValueError(f"state.mode = {state.mode} contradicts v - V = "
                         f"{state.v - params.V!r}; build the state with OscillatorState.start")


#: What a call whose scan alone is over its step budget may do (``check_scan_steps``).
_SCAN_REMEDY = ("shorten the span, check these values, or raise max_steps (up to "
                f"{MAX_SCAN_STEPS:g}) if the wait is intended")


def check_scan_steps(P_rows: np.ndarray, spans: np.ndarray,
                     remedy: str = "shorten the span or check these values",
                     cap: float = MAX_SCAN_STEPS) -> float:
    """``ValueError`` if a run (row ``i`` of ``P_rows`` over ``spans[i]``) has slip stiffer
    than ``params.SLIP_STIFFNESS_LIMIT`` or needs more than ``cap`` scan steps (default
    ``MAX_SCAN_STEPS``; the environments cap one control
    interval far lower, see ``fricenv.envs.scenes.MAX_INTERVAL_SCAN_STEPS``).

    Event-driven runs step at most half a radian of the fastest active tone (and 1 / rate
    when over-damped), so a very fast tone or stiff damping would otherwise run for hours
    without a word. Returns the most scan steps a row needs.
    """
    stiff = law_stiffness(P_rows)
    if np.any(stiff > SLIP_STIFFNESS_LIMIT):
        P = P_rows[int(np.argmax(stiff > SLIP_STIFFNESS_LIMIT))]
        law = law_of_code(P[P_LAW])
        values = {p.name: float(P[P_LAW_PARAMS + i]) for i, p in enumerate(law.params)}
        raise ValueError(
            f"slip is too stiff for the event method: |dv'/dv| reaches "
            f"{float(np.max(stiff)):.3g} near the belt speed (lam = {P[P_LAM]:.6g}, "
            f"{law.name} law {values}), beyond SLIP_STIFFNESS_LIMIT = "
            f"{SLIP_STIFFNESS_LIMIT:g}: its steps would be shorter than "
            f"{2.5 / SLIP_STIFFNESS_LIMIT:g} (keep lam - b1 of the cubic law, or lam + cv "
            f"+ (xfs - xfk) / vs of the exponential law, within the limit)")
    most, i = core.most_scan_steps(P_rows, spans)
    if most > cap:
        P = P_rows[i]
        raise ValueError(
            f"these parameters need about {most:.4g} scan steps over a span of "
            f"{spans[i]:.6g} (at most {cap:g}): the step is bounded by the fastest "
            f"tone (eta = {P[P_W1]:.6g}, nu * eta = {P[P_W2]:.6g}) and the damping "
            f"(lam = {P[P_LAM]:.6g}); {remedy}"
        )
    return float(most)


def resolve_method(params: OscillatorParams, method: str) -> str:
    """The method that will run: ``"auto"`` -> exact for the Coulomb law, event otherwise;
    validate the name.

    ``"exact"`` with a tone too close to resonance for the closed form (a gain over
    ``core.constants.CLOSED_FORM_MAX_GAIN``, where it would cancel its own digits) resolves to
    ``"event"``, as the kernels fall back, so that a result names the method that made it.
    """
    if not isinstance(method, str):
        raise TypeError(f"method must be 'auto' or one of {sorted(METHODS)}, {got(method)}")
    if method == "auto":
        method = "exact" if params.is_coulomb else "event"
    elif method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected 'auto' or one of {sorted(METHODS)}")
    elif method == "exact" and not params.is_coulomb:
        raise ValueError(
            f"method 'exact' needs the Coulomb law, got the {params.law_spec.name} law "
            f"({params.law_values()}); use 'event' or 'auto'"
        )
    if method == "exact" and not core.closed_form_conditioned(params.to_array()):
        return "event"
    return method


def _damping_cause(P: np.ndarray) -> str:
    """Why a plant's slip runs away, or "": negative net damping (``FrictionLaw.runs_away``:
    b1 > lam with b3 = 0, or b3 < 0, for the cubic law)."""
    law = law_of_code(P[P_LAW])
    values = {p.name: float(P[P_LAW_PARAMS + i]) for i, p in enumerate(law.params)}
    if law.runs_away(values, float(P[P_LAM])):
        shown = ", ".join(f"{k} = {v:g}" for k, v in values.items())
        return (f"slip has negative net damping (lam = {P[P_LAM]:g}, {shown}: b1 > lam "
                f"with b3 = 0, or b3 < 0)")
    return ""


def _raise_status(status: int, t: float, max_events: int, t_span: float, P: np.ndarray,
                  budget: tuple[float, float] = (MAX_STEPS_PER_TAU, MAX_STEPS_PER_CALL)
                  ) -> None:
    cause = _damping_cause(P) if status != STATUS_OK else ""
    if cause and status in (STATUS_STEP_BUDGET, STATUS_EVENT_CAP, STATUS_NONFINITE,
                            STATUS_TOO_STIFF):
        raise SimulationError(f"the motion ran away by t = {t:.6g}: {cause}", status)
    if status == STATUS_STEP_BUDGET:
        raise SimulationError(
            f"stopped at t = {t:.6g} after more steps than the budget allows "
            f"({budget[0]:g} in a unit of tau, {budget[1]:g} in the call): slip far stiffer "
            "than the model's O(1) scale or a state far from it "
            "needs too many steps; if this run is meant, raise max_steps_per_tau / "
            "max_steps", status)
    if status == STATUS_EVENT_CAP:
        raise SimulationError(
            f"more than {max_events} switching events in a span of {t_span:g} (stopped at "
            f"t = {t:.6g}): the run chatters between stick and slip; raise max_event_rate "
            "if this is physical", status)
    if status == STATUS_NONFINITE:
        raise SimulationError(f"the state became non-finite at t = {t:.6g}", status)
    if status == STATUS_TOO_STIFF:
        raise SimulationError(
            f"slip at t = {t:.6g} is stiffer than the smallest step the time resolution allows "
            f"(1e-13 max(1, |t|)) can follow: |v - V| far beyond the model's O(1) scale with "
            f"the cubic law (about 5e6 at t < 1), or stiff slip continued at a large t", status)
    if status != STATUS_OK:
        raise SimulationError(f"kernel returned status {status} at t = {t:.6g}", status)


def _raise_if_diverged(P: np.ndarray, x0: float, v0: float, t_span: float,
                       stats: np.ndarray, S: np.ndarray) -> None:
    """``SimulationError`` (``STATUS_DIVERGED``) for a run the kernel finished but whose
    motion ran away (:mod:`fricenv.divergence`): its statistics would be inf, NaN or
    astronomically large numbers presented as a result."""
    if not divergence.run_diverged(P, x0, v0, t_span, stats, S[S_X], S[S_V]):
        return
    limit = float(divergence.motion_limit(P, x0, v0, t_span))
    size = max(abs(stats[k]) for k in (ST_V_MAX, ST_V_MIN, ST_X_MAX, ST_X_MIN))
    cause = _damping_cause(P)
    why = f"; {cause}" if cause else ""
    raise SimulationError(
        f"the motion diverged by t = {S[S_T]:.6g}: |x| or |v| reached {size:.3g} and the "
        f"integral of (v - V)^2 {stats[ST_VR2_INT]:.3g}, beyond {limit:.3g} "
        f"({divergence.DIVERGENCE_FACTOR:g} times the largest motion this plant's parameters "
        f"and start set, times the span){why}", STATUS_DIVERGED)


def _check_rk4_budget(t_span: float, dt: float, budget: tuple[float, float]) -> None:
    """``SimulationError`` (STATUS_STEP_BUDGET) before an RK4 run over budget."""
    per_tau = 1.0 / dt if t_span >= 1.0 else t_span / dt
    if per_tau > budget[0] or t_span / dt > budget[1]:
        raise SimulationError(
            f"dt = {dt!r} needs {t_span / dt:.3g} RK4 steps ({1.0 / dt:.3g} in a unit of "
            f"tau), beyond the budget ({budget[0]:g} in a unit of tau, {budget[1]:g} in the "
            "call); raise max_steps_per_tau / max_steps if this run is meant",
            STATUS_STEP_BUDGET)


def output_times(t0: float, t_end: float, dt_out: float) -> np.ndarray:
    """t0, t0 + dt_out, ... up to t_end (``t_end > t0``); t_end itself is appended if off
    the grid, and replaces a last grid point within rounding of it, but never t0 (a span
    under 1e-9 dt_out gives [t0, t_end], not a run of length 0)."""
    span = t_end - t0
    n = int(math.floor(span / dt_out * (1.0 + 1e-12) + 1e-9))
    t = t0 + dt_out * np.arange(n + 1)
    if n == 0 or span - n * dt_out > 1e-9 * dt_out:
        t = np.append(t, t_end)
    else:
        t[-1] = t_end
    return t


def _output_grid(t0: float, t_span: float, dt_out: float) -> np.ndarray:
    """``output_times`` from ``t0`` over ``t_span``; ``ValueError`` naming ``dt_out`` where
    instants collide in float64 (a grid finer than the spacing of doubles at ``t0``
    recorded some instants twice and others not at all)."""
    out_t = output_times(0.0, t_span, dt_out)
    if t0 != 0.0:  # the grid counts from the start, as the kernels' time does
        out_t = t0 + out_t
        steps = np.diff(out_t)
        if not np.all(steps > 0.0):
            k = int(np.argmin(steps > 0.0))
            raise ValueError(
                f"dt_out = {dt_out!r} is too fine for a start at state.t = {t0!r}: output "
                f"instants {k} and {k + 1} are both t = {out_t[k]!r} in float64 (doubles are "
                f"{math.ulp(out_t[-1]):.3g} apart there); use a larger dt_out or start the "
                "run at a smaller t")
    return out_t


#: Keywords ``simulate`` took before it shared ``run_stats``' vocabulary (``t_span`` for the
#: run's length, ``state`` for where it starts); they still work, with a
#: ``DeprecationWarning``, and go in a later release.
DEPRECATED_SIMULATE_KEYWORDS = ("t_end", "x0", "v0", "phase1", "phase2")


def _deprecated_start(params: OscillatorParams, t_span: float | None,
                      state: OscillatorState | None, old: dict[str, Any]
                      ) -> tuple[float, OscillatorState]:
    """``(t_span, state)`` from the new keywords or the deprecated ones (never both)."""
    unknown = sorted(set(old) - set(DEPRECATED_SIMULATE_KEYWORDS))
    if unknown:
        raise TypeError(f"simulate() got unexpected keyword argument(s) {unknown}")
    if old:
        names = ", ".join(sorted(old))
        warnings.warn(f"simulate(): {names} {'is' if len(old) == 1 else 'are'} deprecated; "
                      "pass t_span "
                      "(the run's length) and state=OscillatorState.start(params, x0, v0, "
                      "phase1=..., phase2=...), as run_stats takes them",
                      DeprecationWarning, stacklevel=3)
    if "t_end" in old:
        if t_span is not None:
            raise TypeError("simulate() got both t_span and its deprecated name t_end")
        t_span = old.pop("t_end")
    if t_span is None:
        raise TypeError("simulate() missing the run's length: simulate(params, t_span)")
    if old:
        if state is not None:
            raise TypeError(f"simulate() got both state and {', '.join(sorted(old))}; "
                            "give the start in state alone")
        state = OscillatorState.start(params, **old)
    return t_span, state if state is not None else OscillatorState.start(params)


def simulate(
    params: OscillatorParams,
    t_span: float | None = None,
    *,
    state: OscillatorState | None = None,
    dt_out: float = 0.1,
    method: str = "auto",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    dt: float = 0.04,
    max_event_rate: float = MAX_EVENT_RATE,
    max_steps_per_tau: float | None = None,
    max_steps: float | None = None,
    wrt: Sequence[str] | None = None,
    t_eval: np.ndarray | Sequence[float] | None = None,
    **deprecated: Any,
) -> Trajectory:
    """Simulate for ``t_span`` from ``state`` (default: rest at t = 0), recording the state
    every ``dt_out``.

    ``method``: ``"exact"`` (closed form, Coulomb law), ``"event"`` (Taylor-series
    steps in slip, any law; ``rtol``/``atol`` set its accuracy), ``"rk4"`` (the paper's
    fixed-step scheme with step ``dt``; it cannot stick) or ``"auto"`` (exact where it
    applies, event otherwise). ``dt`` is checked (a finite number > 0) whatever the method,
    though only ``"rk4"`` uses it, so a bad value never passes unseen. Output times are
    ``state.t``, then every ``dt_out`` on, and the end ``state.t + t_span`` (appended when
    off the grid): always at least the start and the end, at most ``MAX_OUTPUTS`` of
    them, and distinct in float64 (a grid finer than the spacing of doubles at
    ``state.t`` is refused); the steps the grid adds are not charged to the step budget,
    so the budget bounds the motion's work, not the output's. ``t_span`` and ``state`` mean
    what they mean in :func:`run_stats`; the older keywords ``t_end``, ``x0``, ``v0``,
    ``phase1`` and ``phase2`` still work, with a ``DeprecationWarning``. A run that
    cannot go on, or whose motion diverged (:mod:`fricenv.divergence`), raises
    :class:`SimulationError` with its ``status``. ``max_steps_per_tau`` and ``max_steps``
    bound the work (see :func:`run_stats`); Ctrl-C stops the call within about a second.

    ``wrt`` (parameter names, see :func:`fricenv.sensitivity.valid_wrt`) also returns the
    derivatives of x, v and the switching times by each (``dx_dp``, ``dv_dp``,
    ``event_t_dp``), exact through every switch; the event method carries them, so
    ``method`` must then be ``"auto"`` or ``"event"``.

    ``t_eval`` replaces the ``dt_out`` grid by given output instants (a measured record's
    times, say): increasing, starting at ``state.t``; ``t_span`` may then be left out (it
    is ``t_eval[-1] - state.t``).
    """
    _check_params(params)
    span_given = t_span is not None or "t_end" in deprecated
    t_span, state = _deprecated_start(  # (a placeholder span where t_eval gives it)
        params, t_span if span_given or t_eval is None else 1.0, state, deprecated)
    if t_eval is not None:
        t_eval, t_span = _check_t_eval(t_eval, state, t_span if span_given else None)
    t_span = _positive("t_span", t_span)
    if not isinstance(state, OscillatorState):
        raise TypeError(f"state must be an OscillatorState, got {type(state).__name__}")
    check_start(state, params, t_span)
    dt_out = _positive("dt_out", dt_out)
    dt = _positive("dt", dt)  # every method: dt='abc' passed silently unless method='rk4'
    rtol = check_rtol(rtol)
    atol = _positive("atol", atol)
    max_event_rate = _positive("max_event_rate", max_event_rate)
    budget = calls.step_budget(max_steps_per_tau, max_steps)
    if wrt is not None:
        wrt = sensitivity.check_wrt(params, wrt, state.mode == 0)
        method = _tangent_method(method)
    method = resolve_method(params, method)
    if t_eval is None and t_span / dt_out + 1.0 > MAX_OUTPUTS:
        raise ValueError(f"dt_out = {dt_out!r} asks for {t_span / dt_out:.3g} output instants up "
                         f"to t_span = {t_span!r} (at most {MAX_OUTPUTS:g}); use a larger dt_out, "
                         "record the run in pieces (each from the last one's final_state), or "
                         "use run_stats, which keeps no trajectory")
    P = params.to_array()
    scan_steps = 0.0
    if method != "rk4":  # before the output arrays are allocated
        scan_steps = check_scan_steps(P[None], np.array([t_span]), _SCAN_REMEDY,
                                      min(MAX_SCAN_STEPS, budget[1]))
    out_t = _output_grid(state.t, t_span, dt_out) if t_eval is None else t_eval
    n = out_t.shape[0]
    out_x = np.empty(n)
    out_v = np.empty(n)
    out_mode = np.empty(n)
    stats = np.empty(N_STATS)
    if method == "rk4":
        if t_span / dt > MAX_SCAN_STEPS:
            raise ValueError(f"dt = {dt!r} needs {t_span / dt:.3g} RK4 steps to reach "
                             f"t_span = {t_span!r} (at most {MAX_SCAN_STEPS:g})")
        _check_rk4_budget(t_span, min(dt, t_span), budget)
        S = state.to_array()
        core.reset_stats(stats)
        # a span under 1e-9 dt would take no step (and fill no output); over (1e-9 dt, dt]
        # the one step is t_span long either way
        status = core.run_rk4(P, S, t_span, min(dt, t_span), out_t, stats, out_x, out_v,
                              out_mode)
        _raise_status(status, S[S_T], 0, t_span, P)
        _raise_if_diverged(P, state.x, state.v, t_span, stats, S)
        empty = np.empty(0)
        return Trajectory(params, method, out_t, out_x, out_v, out_mode.astype(np.int8),
                          empty, np.empty(0, np.int8), empty,
                          RunStats.from_array(stats, OscillatorState.from_array(S)))
    max_events = int(min(max_event_rate * max(t_span, 1.0), 2**62))
    code = METHOD_EXACT if method == "exact" else METHOD_EVENT
    # A periodic run switches a few times per forcing period; start there, grow if needed.
    w = max(params.omega1, params.omega2, 1.0)
    capacity = int(min(max_events + 1, 64 + 8 * t_span * w / (2 * math.pi)))
    if wrt is not None:
        return _simulate_tangent(params, state, wrt, out_t, (rtol, atol, max_events),
                                 (budget, capacity, scan_steps + n))
    counts = np.zeros(2, np.int64)
    record = core.kernels_for(code, P).record  # compiles this method's kernels only
    # a Solver's and a Recording's fields as plain tuples, numba's fastest (see core.api)
    solver = (code, rtol, atol, max_events)
    S0 = state.to_array()
    S = S0.copy()
    while True:
        ev_t = np.empty(capacity)
        ev_kind = np.empty(capacity, np.int8)
        ev_x = np.empty(capacity)

        def run(work: np.ndarray, ev_t: np.ndarray = ev_t, ev_kind: np.ndarray = ev_kind,
                ev_x: np.ndarray = ev_x) -> int:
            S[:] = S0
            core.reset_stats(stats)
            counts[:] = 0
            rec = (out_t, out_x, out_v, out_mode, ev_t, ev_kind, ev_x, counts)
            return record(P, S, stats, solver, rec, work)

        # (the budget does not charge the steps the grid adds, so count them here: a call
        # with many outputs goes to the worker thread, where Ctrl-C reaches it)
        status = calls.run_call(run, lambda: calls.new_workspace(budget), scan_steps + n)
        if status != STATUS_BUFFER_FULL:
            break
        capacity *= 4
    _raise_status(status, S[S_T], max_events, t_span, P, budget)
    _raise_if_diverged(P, state.x, state.v, t_span, stats, S)
    k = int(counts[0])
    return Trajectory(params, method, out_t, out_x, out_v, out_mode.astype(np.int8),
                      ev_t[:k].copy(), ev_kind[:k].copy(), ev_x[:k].copy(),
                      RunStats.from_array(stats, OscillatorState.from_array(S)))


def _check_t_eval(t_eval: object, state: OscillatorState, t_span: float | None
                  ) -> tuple[np.ndarray, float]:
    """``t_eval`` as a float64 array, and the span it covers; ``ValueError`` naming the
    first bad instant (not finite, not increasing, not starting at ``state.t``, or
    ending elsewhere than ``state.t + t_span``)."""
    t = np.array(t_eval, dtype=np.float64, ndmin=1)
    if t.dtype != np.float64:
        raise TypeError(f"t_eval must hold real numbers, {got(t_eval)}")
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"t_eval must be a 1-d array of at least 2 instants, got shape "
                         f"{t.shape}")
    if t.size > MAX_OUTPUTS:
        raise ValueError(f"t_eval holds {t.size} instants, more than MAX_OUTPUTS = "
                         f"{MAX_OUTPUTS:g}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(f"t_eval[{bad[0]}] = {float(t[bad[0]])!r} is not finite")
    steps = np.flatnonzero(np.diff(t) <= 0.0)
    if steps.size:
        k = int(steps[0])
        raise ValueError(f"t_eval must increase: t_eval[{k + 1}] = {float(t[k + 1])!r} "
                         f"follows t_eval[{k}] = {float(t[k])!r}")
    if t[0] != state.t:
        raise ValueError(f"t_eval[0] = {float(t[0])!r} must be the start's time state.t = "
                         f"{state.t!r}")
    span = float(t[-1] - t[0])
    if t_span is not None and span != t_span:
        raise ValueError(f"t_eval ends at {float(t[-1])!r}, but t_span = {t_span!r} ends at "
                         f"{state.t + t_span!r}; give one of them")
    return t, span


def _tangent_method(method: str) -> str:
    """The method of a run with ``wrt``: the event method, whose series carry the
    derivatives; ``ValueError`` for another."""
    if method not in ("auto", "event"):
        raise ValueError(f"wrt needs method 'auto' or 'event' (the event method carries the "
                         f"derivatives; it agrees with the Coulomb closed form to about "
                         f"1e-10), got method={method!r}")
    return "event"


def _simulate_tangent(params: OscillatorParams, state: OscillatorState, wrt: tuple[str, ...],
                      out_t: np.ndarray, settings: tuple[float, float, int],
                      limits: tuple[tuple[float, float], int, float]) -> Trajectory:
    """``simulate`` with ``wrt``: the event method's run, carrying the tangent
    (``limits`` as in :func:`fricenv.sensitivity.record`)."""
    budget = limits[0]
    seed, P = sensitivity.seeds(params, wrt)
    run = sensitivity.record(P, state.to_array(), seed, out_t, settings, limits)
    t_span = float(out_t[-1] - out_t[0])
    _raise_status(run.status, run.state[S_T], settings[2], t_span, P, budget)
    _raise_if_diverged(P, state.x, state.v, t_span, run.stats, run.state)
    stats = RunStats.from_array(run.stats, OscillatorState.from_array(run.state))
    d = {"vr2_integral": run.d_stats[0].copy(), "stick_time": run.d_stats[1].copy(),
         "x": run.dx_dp[-1].copy(), "v": run.dv_dp[-1].copy()}
    return Trajectory(params, "event", out_t, run.out_x, run.out_v,
                      run.out_mode.astype(np.int8), run.ev_t, run.ev_kind, run.ev_x,
                      dataclasses.replace(stats, wrt=wrt, derivatives=d),
                      wrt, run.dx_dp, run.dv_dp, run.ev_dt_dp, run.singular)


def _stats_tangent(params: OscillatorParams, state: OscillatorState, t_span: float,
                   wrt: Sequence[str], settings: tuple[float, float, int],
                   budget: tuple[float, float], scan_steps: float) -> RunStats:
    """``run_stats`` with ``wrt``: a run recorded at its two ends only, with the tangent."""
    names = sensitivity.check_wrt(params, wrt, state.mode == 0)
    out_t = np.array([state.t, state.t + t_span])
    w = max(params.omega1, params.omega2, 1.0)
    capacity = int(min(settings[2] + 1, 64 + 8 * t_span * w / (2 * math.pi)))
    return _simulate_tangent(params, state, names, out_t, settings,
                             (budget, capacity, scan_steps + 2)).stats


def run_stats(
    params: OscillatorParams,
    t_span: float,
    *,
    state: OscillatorState | None = None,
    method: str = "auto",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_event_rate: float = MAX_EVENT_RATE,
    max_steps_per_tau: float | None = None,
    max_steps: float | None = None,
    wrt: Sequence[str] | None = None,
) -> RunStats:
    """Advance by ``t_span`` from ``state`` (default: rest at t = 0) storing no trajectory.

    Returns stick time, switch counts, exact extrema, the integral of (v - V)^2 and the
    final state, from which a later call continues (possibly with other u0 or nu: the tone
    phases carry over, so the force stays continuous). Every statistic returned is finite,
    and the stick time at most the duration: a run that cannot go on (chattering, too
    stiff, a non-finite state) or whose motion diverged (:mod:`fricenv.divergence`) raises
    :class:`SimulationError` with its ``status`` instead.

    The call's work is bounded: at most ``max_steps_per_tau`` integrator steps in each unit
    of tau (counted window by window from the call's start) and ``max_steps`` in the call
    (None: ``MAX_STEPS_PER_TAU`` = 1e6 and ``MAX_STEPS_PER_CALL`` = 1e7, which no ordinary
    run reaches). Beyond either it raises :class:`SimulationError` with ``status``
    ``STATUS_STEP_BUDGET`` within about a second (slip far stiffer than the model's scale,
    or a start far from it). Ctrl-C stops the call within about a second, raising
    ``KeyboardInterrupt`` and leaving ``state`` as it was.

    ``wrt`` (parameter names, as in :func:`simulate`) also returns the derivatives of the
    (v - V)^2 integral, the stick time and the final x and v by each
    (``RunStats.derivatives``), exact through every switch, from the event method.
    """
    _check_params(params)
    t_span = _positive("t_span", t_span)
    if wrt is not None:
        method = _tangent_method(method)
    method = resolve_method(params, method)
    if method == "rk4":
        raise ValueError("run_stats needs an event-driven method ('exact' or 'event'), got 'rk4'")
    if state is None:
        state = OscillatorState.start(params)
    elif not isinstance(state, OscillatorState):
        raise TypeError(f"state must be an OscillatorState, got {type(state).__name__}")
    else:
        check_start(state, params, t_span)
    max_event_rate = _positive("max_event_rate", max_event_rate)
    max_events = int(min(max_event_rate * max(t_span, 1.0), 2**62))
    budget = calls.step_budget(max_steps_per_tau, max_steps)
    rtol = check_rtol(rtol)
    atol = _positive("atol", atol)
    P = params.to_array()
    scan_steps = check_scan_steps(P[None], np.array([t_span]), _SCAN_REMEDY,
                                  min(MAX_SCAN_STEPS, budget[1]))
    if wrt is not None:
        return _stats_tangent(params, state, t_span, wrt, (rtol, atol, max_events), budget,
                              scan_steps)
    S0 = state.to_array()
    S = S0.copy()
    stats = np.empty(N_STATS)
    code = METHOD_EXACT if method == "exact" else METHOD_EVENT
    advance = core.kernels_for(code, P).advance  # compiles this method's kernels only
    solver = (code, rtol, atol, max_events)  # a Solver's fields, plain (see core.api)

    def run(work: np.ndarray) -> int:
        S[:] = S0
        core.reset_stats(stats)
        return advance(P, S, t_span, stats, solver, work)

    status = calls.run_call(run, lambda: calls.new_workspace(budget), scan_steps)
    _raise_status(status, S[S_T], max_events, t_span, P, budget)
    _raise_if_diverged(P, state.x, state.v, t_span, stats, S)
    return RunStats.from_array(stats, OscillatorState.from_array(S))
