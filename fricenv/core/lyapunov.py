"""The largest Lyapunov exponent of a run, from its exact tangent (non-smooth systems).

A tangent vector in (x, v) is carried through stick, slip and every switch by the
saltation conditions of :mod:`fricenv.core.tangent`, and renormalised at fixed intervals:
Benettin's scheme, which Mueller (1995) extended to systems with discontinuities by
exactly these jump conditions. The exponent is the mean growth rate of its log-length.
In stick a perturbation of v is absorbed at once (v is held at V); one of x is carried,
and moves the break-away.
"""

import math
from typing import NamedTuple

import numpy as np
from numba import prange

from ..jit import kernel
from ..layout import N_STATS, STATUS_OK
from .constants import TIME_REL_TOL
from .event import _run_event
from .recording import Recording, stats_only
from .tangent import N_LEVEL_ROWS, N_TONE_ROWS, SEED_DTYPE, Tangent, _run_tangent
from .workspace import TAYLOR_MAX_ORDER

#: Points without a derivative a chunk may note (the chunk is then left out).
_FLAGS = 4


@kernel
def _chunk_map(P, S, t_chunk, settings, bufs, cx):
    """Run ``t_chunk`` from S with the tangent seeded by (x0, v0) (columns 0 and 1 of
    ``bufs`` = (recording, tangent, statistics)), leaving the chunk's 2x2 map of (dx, dv)
    in the tangent's ``y``; the status, or -1 if the chunk met a point without a
    derivative."""
    rec, tan, stats = bufs
    rec.out_t[0] = 0.0
    rec.out_t[1] = t_chunk
    rec.counts[0] = 0
    rec.counts[1] = 0
    tan.n_flags[0] = 0
    status = _run_tangent(P, S, t_chunk, settings, bufs, cx)
    if status == STATUS_OK and tan.n_flags[0] > 0:
        return -1
    return status


@kernel
def _lyapunov(P, S, t_span, t_renorm, settings, bufs, cx):
    """Largest Lyapunov exponent over ``t_span`` from S (advanced in place): a tangent
    vector carried through stick, slip and every switch (saltation), renormalised every
    ``t_renorm`` (Mueller 1995 for non-smooth systems; Benettin's scheme otherwise).
    Chunks that meet a point without a derivative are left out (their time too). Returns
    (status, exponent, time counted)."""
    tan = bufs[1]
    u0 = 1.0 / math.sqrt(2.0)
    u1 = u0
    total = 0.0
    counted = 0.0
    t = 0.0
    status = STATUS_OK
    while t_span - t > TIME_REL_TOL * max(1.0, t_span):
        chunk = min(t_renorm, t_span - t)
        status = _chunk_map(P, S, chunk, settings, bufs, cx)
        t += chunk
        if status == -1:
            status = STATUS_OK
            continue
        if status != STATUS_OK:
            break
        a = tan.y[0, 0] * u0 + tan.y[1, 0] * u1
        b = tan.y[0, 1] * u0 + tan.y[1, 1] * u1
        r = math.sqrt(a * a + b * b)
        if not r > 0.0:  # every perturbation absorbed (stick): start a fresh direction
            u0 = 1.0 / math.sqrt(2.0)
            u1 = u0
            continue
        total += math.log(r)
        counted += chunk
        u0 = a / r
        u1 = b / r
    return status, (total / counted if counted > 0.0 else math.nan), counted



class WorkerBuffers(NamedTuple):
    """Each worker's buffers of a parallel Lyapunov run (leading axis: worker), made by
    :func:`worker_buffers`; ``seed``, the tangent's (x0, v0) columns, is shared."""

    seed: np.ndarray
    out_t: np.ndarray
    out: np.ndarray
    ev_t: np.ndarray
    ev_kind: np.ndarray
    ev_x: np.ndarray
    counts: np.ndarray
    y: np.ndarray
    d_out: np.ndarray
    d_stats: np.ndarray
    ev_dt: np.ndarray
    flags: np.ndarray
    n_flags: np.ndarray
    series: np.ndarray
    ser: np.ndarray
    stats: np.ndarray
    work: np.ndarray


def worker_buffers(n_workers: int, event_cap: int) -> WorkerBuffers:
    """Buffers for ``n_workers`` workers whose renormalisation intervals hold at most
    ``event_cap`` switches."""
    from .workspace import new_workspace

    L = TAYLOR_MAX_ORDER + 2
    seed = np.zeros(2, SEED_DTYPE)
    seed[0]["x0"] = 1.0
    seed[1]["v0"] = 1.0
    w = n_workers
    return WorkerBuffers(
        seed, np.zeros((w, 2)), np.empty((w, 3, 2)), np.empty((w, event_cap)),
        np.empty((w, event_cap), np.int8), np.empty((w, event_cap)),
        np.zeros((w, 2), np.int64), np.empty((w, 2, 2)), np.empty((w, 2, 2, 2)),
        np.zeros((w, 2, 2)),
        np.empty((w, event_cap, 2)), np.empty((w, _FLAGS, 2)), np.zeros((w, 1), np.int64),
        np.empty((w, N_LEVEL_ROWS + N_TONE_ROWS + 1, L)), np.empty((w, 2, 2, L)),
        np.zeros((w, N_STATS)), new_workspace(w, extrema=False, vr2=False))


@kernel
def _worker(B, w):
    """Worker w's (recording, tangent, statistics) and workspace: views of ``B``."""
    o = B.out[w]
    rec = Recording(B.out_t[w], o[0], o[1], o[2], B.ev_t[w], B.ev_kind[w], B.ev_x[w],
                    B.counts[w])
    ser = B.series[w]
    tan = Tangent(B.seed, B.y[w], B.d_out[w, 0], B.d_out[w, 1], B.ev_dt[w], B.d_stats[w],
                  B.flags[w], B.n_flags[w], ser[:N_LEVEL_ROWS], ser[N_LEVEL_ROWS:], B.ser[w])
    return (rec, tan, B.stats[w]), B.work[w]


@kernel
def _worker_rows(P_rows, S_rows, spans, settings, B, out, w):
    """Worker w's share of ``lyapunov_rows``: rows w, w + n_workers, ... (the views of its
    buffers are made and used here, where no reference counting runs)."""
    rtol, atol, max_events = settings
    bufs, cx = _worker(B, w)
    for i in range(w, P_rows.shape[0], B.work.shape[0]):
        status = _run_event(P_rows[i], S_rows[i], spans[i, 0], bufs[2], max_events * (
            1 + int(spans[i, 0] / spans[i, 2])), rtol, atol, stats_only(cx), cx)
        exponent = math.nan
        counted = 0.0
        if status == STATUS_OK:
            status, exponent, counted = _lyapunov(P_rows[i], S_rows[i], spans[i, 1],
                                                  spans[i, 2], settings, bufs, cx)
        out[i, 0] = exponent
        out[i, 1] = counted
        out[i, 2] = status


@kernel(parallel=True, allocates=True, nogil=True)
def lyapunov_rows(P_rows, S_rows, spans, settings, B, out):
    """For each plant (row of ``P_rows``, start ``S_rows``, advanced in place): skip the
    transient ``spans[i, 0]`` (a stats-only run), then measure the largest Lyapunov
    exponent over ``spans[i, 1]``, renormalising every ``spans[i, 2]``, on the workers of
    ``B`` (:func:`worker_buffers`; rows are dealt out in turn). ``settings``: (rtol, atol,
    events allowed in one renormalisation interval). ``out[i]`` = (exponent, time
    counted, status)."""
    for w in prange(B.work.shape[0]):
        _worker_rows(P_rows, S_rows, spans, settings, B, out, w)
