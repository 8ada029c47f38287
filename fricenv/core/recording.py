"""What a recording run writes: the state on an output grid and every switching event.

The arrays travel together as one :class:`Recording`. A stats-only run passes an empty one
(:func:`stats_only`: no output instant, no event buffer), so that one compiled runner serves
both kinds of call; the runners branch on :func:`recording` at run time, once per call or
per event.
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


@kernel
def stats_only(work):
    """The empty :class:`Recording` of a stats-only call: zero-length views of the workspace
    ``work`` (so making one allocates nothing), of the dtypes a recording run's arrays have."""
    f = work[:0]
    return Recording(f, f, f, f, f, work.view(np.int8)[:0], f, work.view(np.int64)[:0])


@kernel
def recording(rec):
    """Whether ``rec`` records (a recording run has at least its start's output instant)."""
    return rec.out_t.shape[0] > 0


@kernel
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


@kernel
def _log_event(rec, t, kind, x, n_events, max_events):
    """Record switch number ``n_events`` when recording; the run's status after it."""
    status = STATUS_OK
    if recording(rec):
        if not _record_event(rec, t, kind, x):
            status = STATUS_BUFFER_FULL
    if n_events > max_events:
        status = STATUS_EVENT_CAP
    return status


@kernel
def _write_output(rec, j, x, v, mode):
    """The state at output instant ``j``, when recording."""
    if recording(rec):
        rec.out_x[j] = x
        rec.out_v[j] = v
        rec.out_mode[j] = mode
