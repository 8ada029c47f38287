"""What a recording run writes: the state on an output grid and every switching event.

The arrays travel together as one :class:`Recording`; a stats-only run passes ``None``
instead, and numba then compiles the runner without any of the recording code (a branch on
``rec is not None`` is decided when the function is compiled, not when it runs).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..jit import kernel
from ..layout import STATUS_BUFFER_FULL, STATUS_EVENT_CAP, STATUS_OK


class Recording(NamedTuple):
    """Output arrays of a recording run (``record``).

    ``out_t``: output instants (the run covers [out_t[0], out_t[-1]]); ``out_x``, ``out_v``,
    ``out_mode``: the state there. ``ev_t``, ``ev_kind``, ``ev_x``: each switch's time,
    kind (``layout.EVENT_*``) and displacement. ``counts``: [events recorded, outputs
    written].
    """

    out_t: np.ndarray
    out_x: np.ndarray
    out_v: np.ndarray
    out_mode: np.ndarray
    ev_t: np.ndarray
    ev_kind: np.ndarray
    ev_x: np.ndarray
    counts: np.ndarray


@kernel(inline=True)
def _record_event(rec, t, kind, x):
    """Append an event to ``rec``; False when its buffer is full."""
    n = rec.counts[0]
    if n >= rec.ev_t.shape[0]:
        return False
    rec.ev_t[n] = t
    rec.ev_kind[n] = kind
    rec.ev_x[n] = x
    rec.counts[0] = n + 1
    return True


@kernel(inline=True)
def _log_event(rec, t, kind, x, n_events, max_events):
    """Record switch number ``n_events`` when recording; the run's status after it."""
    status = STATUS_OK
    if rec is not None:
        if not _record_event(rec, t, kind, x):
            status = STATUS_BUFFER_FULL
    if n_events > max_events:
        status = STATUS_EVENT_CAP
    return status


@kernel(inline=True)
def _write_output(rec, j, x, v, mode):
    """The state at output instant ``j``, when recording."""
    if rec is not None:
        rec.out_x[j] = x
        rec.out_v[j] = v
        rec.out_mode[j] = mode
