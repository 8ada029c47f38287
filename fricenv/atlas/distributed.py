"""Running an atlas's chunks on a Dask cluster (``dask.distributed``).

The client submits one task per chunk, at most a few per worker thread at a time, and
yields each chunk's result as it completes, so it never holds more than that window of
chunks whatever the atlas's size. Workers run :func:`fricenv.atlas.core.compute_chunk`:
the whole chunk in one numba call per friction method, no Python per cell.

Workers may be started by spawn (Dask's default) or fork and may have several threads
(see :mod:`fricenv.jit` on the threading layer). :class:`WarmKernels` loads each worker's
numba cache once, as it joins, so no task pays for it.

A task holds the Python GIL while its kernel runs (numba releases it only with
``nogil``), so the tasks of one worker run one at a time; each therefore uses as many
numba threads as its worker has Dask threads. The usual layout for such code is one
process per core with one thread each (``--nworkers N --nthreads 1``).
"""

from __future__ import annotations

import uuid
from collections.abc import Iterator, Sequence
from typing import Any

import numba
import numpy as np
from distributed import Client, WorkerPlugin, as_completed, get_worker

from ..params import OscillatorParams
from ..sweep import SweepSettings
from .core import ChunkTask, compute_chunk

#: Tasks in flight per worker thread: enough that a worker never waits for the client
#: between chunks, few enough that the client holds little.
IN_FLIGHT_PER_THREAD = 2
#: Name of the warm-up plugin on the workers (registering it again replaces it).
PLUGIN_NAME = "fricenv-atlas-warm"
#: Prefix of the tasks' keys: the dashboard groups the chunks under it.
KEY_PREFIX = "fricenv-atlas-chunk"


def warm_kernels() -> None:
    """Load (or compile) the cell kernels for both methods: one tiny cell each."""
    settings = SweepSettings(transient_min=0.0, transient_efolds=0.0, transient_periods=0.0,
                             window_min=0.1, window_periods=0.0)
    for law in ("coulomb", "stribeck"):
        base = OscillatorParams.preset(law)
        task = ChunkTask((0,), (slice(0, 1),), base, {"u0": np.array([1.0])}, settings, 0.0)
        compute_chunk(task, 1)


class WarmKernels(WorkerPlugin):
    """Warms each worker's numba kernels once, when it starts or joins."""

    name = PLUGIN_NAME
    setups = 0  # (per worker process: how often it warmed, for tests)

    def setup(self, worker: object) -> None:
        warm_kernels()
        self.setups += 1


def _worker_threads() -> int:
    """Numba threads for a task: its worker's Dask threads (tasks run one at a time, see
    the module docstring), within numba's own limit."""
    try:
        n = get_worker().state.nthreads
    except (ValueError, AttributeError):  # not on a worker (a test's direct call)
        n = 1
    config: Any = numba.config  # (numba sets its options as module attributes at run time)
    return max(1, min(int(n), config.NUMBA_NUM_THREADS))


def run_chunk(task: ChunkTask) -> tuple[tuple[int, ...], dict[str, np.ndarray]]:
    """The task a worker runs: one chunk."""
    return compute_chunk(task, _worker_threads())


def _has_plugin(dask_scheduler: object) -> bool:
    return PLUGIN_NAME in getattr(dask_scheduler, "worker_plugins", {})


def ensure_warm_workers(client: Client) -> None:
    """Register :class:`WarmKernels` unless the scheduler has it: each worker then warms
    its kernels once, when it starts or joins, not again at every atlas."""
    try:
        registered = client.run_on_scheduler(_has_plugin)
    except Exception:  # (a scheduler that cannot run functions: register, to be sure)
        registered = False
    if not registered:
        client.register_plugin(WarmKernels(), name=PLUGIN_NAME)


def total_threads(client: Client) -> int:
    return max(1, sum(client.nthreads().values()))


def run_distributed(client: Client, tasks: Sequence[ChunkTask],
                    stats: dict | None = None
                    ) -> Iterator[tuple[tuple[int, ...], dict[str, np.ndarray]]]:
    """Yield each chunk's ``(index, variables)`` as its task completes. At most
    ``IN_FLIGHT_PER_THREAD`` tasks per worker thread are submitted at once; a result is
    released once yielded. ``stats``, if given, gets ``max_in_flight``: the most futures
    held at once (a check that the client's memory is bounded)."""
    ensure_warm_workers(client)
    window = IN_FLIGHT_PER_THREAD * total_threads(client) + 1
    run_id = uuid.uuid4().hex
    todo = iter(tasks)
    pending: set = set()

    def submit(task: ChunkTask) -> None:
        key = f"{KEY_PREFIX}-{run_id}-{'.'.join(map(str, task.index))}"
        fut = client.submit(run_chunk, task, key=key, pure=False)
        pending.add(fut)
        queue.add(fut)

    queue = as_completed([])
    try:
        for task in todo:
            submit(task)
            if len(pending) >= window:
                break
        if stats is not None:
            stats["max_in_flight"] = max(stats.get("max_in_flight", 0), len(pending))
        for fut in queue:
            result = fut.result()
            pending.discard(fut)
            fut.release()
            nxt = next(todo, None)
            if nxt is not None:
                submit(nxt)
            if stats is not None:
                stats["max_in_flight"] = max(stats.get("max_in_flight", 0),
                                             len(pending) + 1)
            yield result
            del result
    finally:
        if pending:  # stopped early (an error, Ctrl-C, the caller closed us): cancel
            client.cancel(list(pending))
