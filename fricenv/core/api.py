"""Entry kernels: the stats-only ``advance`` and the recording ``record``, per method.

Numba compiles a kernel together with everything it calls, whatever branch runs. So each
method has its own entry kernels (``advance_exact``, ``advance_event``, ``record_exact``,
...), and a workload compiles only its method's code: a Coulomb run never compiles the
Taylor or Rosenbrock steps. ``advance``, ``advance_ws`` and ``record`` take the method at
run time and compile both. :func:`kernels_for` picks a plant's entry kernels in Python.

The exact method cannot run a tone too close to resonance (see CLOSED_FORM_MAX_GAIN): its
kernels then return ``_STATUS_NEAR_RESONANCE`` having changed nothing, and the
method-taking kernels run the event method instead. :func:`method_for` makes that choice
before the call, for the per-method kernels.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from ..jit import kernel
from ..layout import METHOD_EVENT, METHOD_EXACT
from .constants import _STATUS_NEAR_RESONANCE, LAM_CONDITIONED
from .context import closed_form_conditioned
from .event import _run_event
from .exact import _run_exact
from .recording import Recording, stats_only


@kernel
def advance_exact_ws(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """``advance_ws`` with the closed form alone (``method``, ``rtol`` and ``atol`` are not
    read): _STATUS_NEAR_RESONANCE, nothing changed, if a tone of P is too close to
    resonance for it (see :func:`method_for`)."""
    return _run_exact(P, S, t_span, stats, max_events, stats_only(work), work)


@kernel
def advance_event_ws(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """``advance_ws`` with the event method alone (``method`` is not read)."""
    return _run_event(P, S, t_span, stats, max_events, rtol, atol, stats_only(work), work)


@kernel
def advance_ws(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """``advance`` with a caller-owned workspace (see ``new_workspace``).

    Reusing one workspace per plant across calls spares the allocation and, for the
    closed-form method, the transition constants and the tone phases' cos/sin, which is
    most of the cost of a short call such as one control interval of an environment.
    """
    if method == METHOD_EXACT:
        status = advance_exact_ws(P, S, t_span, stats, method, rtol, atol, max_events, work)
        if status != _STATUS_NEAR_RESONANCE:
            return status
    return advance_event_ws(P, S, t_span, stats, method, rtol, atol, max_events, work)


@kernel(allocates=True, nogil=True)
def advance_exact(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """``advance`` with the closed form alone (see ``advance_exact_ws``)."""
    return advance_exact_ws(P, S, t_span, stats, method, rtol, atol, max_events, work)


@kernel(allocates=True, nogil=True)
def advance_event(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """``advance`` with the event method alone."""
    return advance_event_ws(P, S, t_span, stats, method, rtol, atol, max_events, work)


@kernel(allocates=True, nogil=True)
def advance(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """Advance the state ``S`` in place by ``t_span``, accumulating ``stats``; no trajectory.

    ``method`` is METHOD_EXACT (Coulomb law only; the caller checks; a call with a tone
    too close to resonance runs the event method, see CLOSED_FORM_MAX_GAIN) or
    METHOD_EVENT.
    Tone phases are carried in ``S``, so P's amplitudes and frequencies may change between
    calls without a jump in the force. Returns a STATUS_* code; at most ``max_events``
    switches are allowed in the call (STATUS_EVENT_CAP beyond), and at most the step
    budget of the workspace (STATUS_STEP_BUDGET beyond, see MAX_STEPS_PER_TAU). ``work``:
    a fresh workspace (``new_workspace``) to run in, whose budget slots bound the call. The
    GIL is released while it runs.
    """
    return advance_ws(P, S, t_span, stats, method, rtol, atol, max_events, work)


@kernel(allocates=True, nogil=True)
def record_exact(P, S, out_t, stats, method, rtol, atol, max_events, out_x, out_v, out_mode,
                 ev_t, ev_kind, ev_x, counts, work):
    """``record`` with the closed form alone (see ``advance_exact_ws``)."""
    rec = Recording(out_t, out_x, out_v, out_mode, ev_t, ev_kind, ev_x, counts)
    t_span = out_t[out_t.shape[0] - 1] - out_t[0]
    return _run_exact(P, S, t_span, stats, max_events, rec, work)


@kernel(allocates=True, nogil=True)
def record_event(P, S, out_t, stats, method, rtol, atol, max_events, out_x, out_v, out_mode,
                 ev_t, ev_kind, ev_x, counts, work):
    """``record`` with the event method alone."""
    rec = Recording(out_t, out_x, out_v, out_mode, ev_t, ev_kind, ev_x, counts)
    t_span = out_t[out_t.shape[0] - 1] - out_t[0]
    return _run_event(P, S, t_span, stats, max_events, rtol, atol, rec, work)


@kernel
def _record_ws(P, S, stats, method, rtol, atol, max_events, rec, work):
    """``record``'s body, in the workspace ``work``."""
    t_span = rec.out_t[rec.out_t.shape[0] - 1] - rec.out_t[0]
    if method == METHOD_EXACT:
        status = _run_exact(P, S, t_span, stats, max_events, rec, work)
        if status != _STATUS_NEAR_RESONANCE:
            return status
    return _run_event(P, S, t_span, stats, max_events, rtol, atol, rec, work)


@kernel(allocates=True, nogil=True)
def record(P, S, out_t, stats, method, rtol, atol, max_events, out_x, out_v, out_mode, ev_t,
           ev_kind, ev_x, counts, work):
    """Like ``advance`` over [out_t[0], out_t[-1]], recording the state at ``out_t`` and the
    events (time, kind, x); ``counts`` returns (events recorded, outputs written). ``work``
    as in ``advance``."""
    rec = Recording(out_t, out_x, out_v, out_mode, ev_t, ev_kind, ev_x, counts)
    return _record_ws(P, S, stats, method, rtol, atol, max_events, rec, work)


def method_for(method: int, P: np.ndarray) -> int:
    """The method that runs plant ``P`` when ``method`` is asked for: METHOD_EVENT for
    METHOD_EXACT where a tone is too close to resonance for the closed form (what
    ``advance`` does inside), else ``method``."""
    if method == METHOD_EXACT and not closed_form_conditioned(P):
        return METHOD_EVENT
    return method


def always_conditioned(lam_min: float) -> bool:
    """Whether the closed form runs every plant whose damping is at least ``lam_min``,
    whatever its tones (see LAM_CONDITIONED): a workload whose plants all qualify never
    needs the event method's fallback."""
    return lam_min >= LAM_CONDITIONED


class EntryKernels(NamedTuple):
    """A method's entry kernels (same arguments as ``advance_ws``, ``advance``,
    ``record``)."""

    advance_ws: Callable[..., Any]
    advance: Callable[..., Any]
    record: Callable[..., Any]


#: Each method's entry kernels; METHOD_EXACT's need a conditioned plant (``method_for``).
ENTRY_KERNELS = {
    METHOD_EXACT: EntryKernels(advance_exact_ws, advance_exact, record_exact),
    METHOD_EVENT: EntryKernels(advance_event_ws, advance_event, record_event),
}


def kernels_for(method: int, P: np.ndarray) -> EntryKernels:
    """The entry kernels that run plant ``P`` by ``method`` (METHOD_EXACT or METHOD_EVENT)
    and compile nothing else."""
    return ENTRY_KERNELS[method_for(method, P)]
