"""Event log of a recording run."""

from ..jit import kernel
from ..layout import STATUS_BUFFER_FULL, STATUS_EVENT_CAP, STATUS_OK


# ----------------------------------------------------------------------------------------
# Shared per-step pieces
# ----------------------------------------------------------------------------------------
@kernel(inline=True)
def _record_event(ev_t, ev_kind, ev_x, counts, t, kind, x):
    n = counts[0]
    if n >= ev_t.shape[0]:
        return False
    ev_t[n] = t
    ev_kind[n] = kind
    ev_x[n] = x
    counts[0] = n + 1
    return True

@kernel(inline=True)
def _log_event(ev_t, ev_kind, ev_x, counts, t, kind, x, n_events, max_events):
    """Record switch number ``n_events`` when a buffer is given; the run's status after it."""
    status = STATUS_OK
    if ev_t is not None:
        if not _record_event(ev_t, ev_kind, ev_x, counts, t, kind, x):
            status = STATUS_BUFFER_FULL
    if n_events > max_events:
        status = STATUS_EVENT_CAP
    return status
