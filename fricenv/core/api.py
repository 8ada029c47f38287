"""Entry kernels: the stats-only ``advance`` and the recording ``record``."""

from ..jit import kernel
from ..layout import METHOD_EXACT
from .constants import _STATUS_NEAR_RESONANCE
from .event import _run_event
from .exact import _run_exact
from .workspace import fresh_workspace


@kernel(inline=True)
def advance_ws(P, S, t_span, stats, method, rtol, atol, max_events, work):
    """``advance`` with a caller-owned workspace (see ``new_workspace``).

    Reusing one workspace per plant across calls spares the allocation and, for the
    closed-form method, the transition constants and the tone phases' cos/sin, which is
    most of the cost of a short call such as one control interval of an environment.
    """
    if method == METHOD_EXACT:
        status = _run_exact(P, S, t_span, None, stats, max_events, None, None, None, None,
                            None, None, None, work)
        if status != _STATUS_NEAR_RESONANCE:
            return status
    return _run_event(P, S, t_span, None, stats, max_events, rtol, atol, None, None, None,
                      None, None, None, None, work)

@kernel(allocates=True)
def advance(P, S, t_span, stats, method, rtol, atol, max_events):
    """Advance the state ``S`` in place by ``t_span``, accumulating ``stats``; no trajectory.

    ``method`` is METHOD_EXACT (Coulomb law only; the caller checks; a call with a tone
    too close to resonance runs the event method, see CLOSED_FORM_MAX_GAIN) or
    METHOD_EVENT.
    Tone phases are carried in ``S``, so P's amplitudes and frequencies may change between
    calls without a jump in the force. Returns a STATUS_* code; at most ``max_events``
    switches are allowed in the call (STATUS_EVENT_CAP beyond).
    """
    return advance_ws(P, S, t_span, stats, method, rtol, atol, max_events, fresh_workspace())

@kernel(allocates=True)
def record(P, S, out_t, stats, method, rtol, atol, max_events, out_x, out_v, out_mode, ev_t,
           ev_kind, ev_x, counts):
    """Like ``advance`` over [out_t[0], out_t[-1]], recording the state at ``out_t`` and the
    events (time, kind, x); ``counts`` returns (events recorded, outputs written)."""
    t_span = out_t[out_t.shape[0] - 1] - out_t[0]
    work = fresh_workspace()
    if method == METHOD_EXACT:
        status = _run_exact(P, S, t_span, out_t, stats, max_events, out_x, out_v, out_mode,
                            ev_t, ev_kind, ev_x, counts, work)
        if status != _STATUS_NEAR_RESONANCE:
            return status
    return _run_event(P, S, t_span, out_t, stats, max_events, rtol, atol, out_x, out_v,
                      out_mode, ev_t, ev_kind, ev_x, counts, work)
