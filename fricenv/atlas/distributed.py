"""Running an atlas's chunks on a Dask cluster (``dask.distributed``).

The client submits one task per chunk, at most a few per worker thread at a time, and
yields each chunk's result as it completes, so it never holds more than that window of
chunks whatever the atlas's size. Workers run :func:`fricenv.atlas.core.compute_chunk`:
the whole chunk in one numba call per friction method, no Python per cell.

Workers may be started by spawn (Dask's default) or fork and may have several threads
(see :mod:`fricenv.jit` on the threading layer). :class:`WarmKernels` loads each worker's
numba cache once, as it joins, so no task pays for it.

The cell kernels release the GIL, so a worker's Dask threads run its tasks at once; each
task asks for as many numba threads as its worker has Dask threads, so that the last
chunk of a run still uses the whole worker, and under TBB the tasks share one pool of
threads rather than oversubscribing the cores. A task polls the run's stop event (a
``distributed.Event``) while its kernel runs, so that :meth:`DistributedRun.stop` ends it
within about a second with the cells it finished.
"""

from __future__ import annotations

import signal
import threading
import uuid
from collections.abc import Iterator, Sequence

import numpy as np
from distributed import Client, WorkerPlugin, as_completed, get_worker

from ..cells import SweepSettings
from ..jit import max_threads
from ..params import OscillatorParams
from .core import ChunkTask, compute_chunk

#: Tasks in flight per worker thread: enough that a worker never waits for the client
#: between chunks, few enough that the client holds little.
IN_FLIGHT_PER_THREAD = 2
#: Name of the warm-up plugin on the workers (registering it again replaces it).
PLUGIN_NAME = "fricenv-atlas-warm"
#: Prefix of the tasks' keys: the dashboard groups the chunks under it.
KEY_PREFIX = "fricenv-atlas-chunk"
#: Longest a stopped run waits for its running chunks to hand back their finished cells
#: (they stop within a poll of the stop event, ``fricenv.calls.JOIN_POLL``, and a few
#: hundred kernel steps; the rest is the trip back from the worker).
STOP_WAIT_S = 10.0


def warm_kernels() -> None:
    """Load (or compile) the cell kernels for both methods: one tiny cell each."""
    settings = SweepSettings(transient_min=0.0, transient_efolds=0.0, transient_periods=0.0,
                             window_min=0.1, window_periods=0.0)
    for law in ("coulomb", "stribeck"):
        base = OscillatorParams.preset(law)
        task = ChunkTask((0,), (slice(0, 1),), base, {"u0": np.array([1.0])}, settings, 0.0)
        compute_chunk(task, 1)


def shield_from_terminal_ctrl_c(has_nanny: bool) -> bool:
    """Ignore SIGINT in this worker process if a nanny manages it, and say whether it did.

    Ctrl-C in a terminal reaches every process of the foreground group: a local cluster's
    worker processes too, where it ended the worker (its ``asyncio`` runner's handler
    cancels the worker) with the chunks it held, finished or not, while the client waited
    for them to hand back their cells. A worker stops on the run's stop event instead,
    and its nanny, which keeps its own handling of signals, ends it. A worker without a
    nanny (``dask worker --no-nanny``: its own process, its own Ctrl-C) is left alone,
    and so is a worker that is a thread of another program."""
    if not has_nanny or threading.current_thread() is not threading.main_thread():
        return False
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return True


class WarmKernels(WorkerPlugin):
    """Warms each worker's numba kernels once, when it starts or joins, and shields its
    process from a terminal's Ctrl-C (:func:`shield_from_terminal_ctrl_c`)."""

    name = PLUGIN_NAME
    setups = 0  # (per worker process: how often it warmed, for tests)

    def setup(self, worker: object) -> None:
        shield_from_terminal_ctrl_c(bool(getattr(worker, "nanny", None)))
        warm_kernels()
        self.setups += 1


def _worker_threads() -> int:
    """Numba threads for a task: its worker's Dask threads (see the module docstring),
    within numba's own limit."""
    try:
        n = get_worker().state.nthreads
    except (ValueError, AttributeError):  # not on a worker (a test's direct call)
        n = 1
    return max(1, min(int(n), max_threads()))


def run_chunk(task: ChunkTask, stop_event: str | None = None
              ) -> tuple[tuple[int, ...], dict[str, np.ndarray]]:
    """The task a worker runs: one chunk. With ``stop_event`` (a ``distributed.Event``'s
    name) the chunk stops once the client sets that event, and returns the cells finished
    so far (the others at their fill values)."""
    stop_requested = None
    if stop_event is not None:
        from distributed import Event

        event = Event(stop_event)
        stop_requested = event.is_set
    return compute_chunk(task, _worker_threads(), stop_requested)


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


class DistributedRun:
    """The chunks of an atlas on a cluster, iterated as ``(index, variables)`` in the order
    they complete.

    At most ``IN_FLIGHT_PER_THREAD`` tasks per worker thread are submitted at once, and a
    result is released once yielded. ``stats``, if given, gets ``max_in_flight``: the most
    futures held at once (a check that the client's memory is bounded). :meth:`stop` ends
    the run early and hands back what its running chunks had finished.
    """

    def __init__(self, client: Client, tasks: Sequence[ChunkTask], stats: dict | None = None
                 ) -> None:
        ensure_warm_workers(client)
        self.client = client
        self.stats = stats
        self.window = IN_FLIGHT_PER_THREAD * total_threads(client) + 1
        self.run_id = uuid.uuid4().hex
        self.stop_event = f"{KEY_PREFIX}-stop-{self.run_id}"
        self.todo = iter(tasks)
        self.pending: set = set()
        self.queue = as_completed([])

    def _submit(self, task: ChunkTask) -> None:
        key = f"{KEY_PREFIX}-{self.run_id}-{'.'.join(map(str, task.index))}"
        fut = self.client.submit(run_chunk, task, self.stop_event, key=key, pure=False)
        self.pending.add(fut)
        self.queue.add(fut)

    def _note_in_flight(self, extra: int = 0) -> None:
        if self.stats is not None:
            self.stats["max_in_flight"] = max(self.stats.get("max_in_flight", 0),
                                              len(self.pending) + extra)

    def __iter__(self) -> Iterator[tuple[tuple[int, ...], dict[str, np.ndarray]]]:
        try:
            for task in self.todo:
                self._submit(task)
                if len(self.pending) >= self.window:
                    break
            self._note_in_flight()
            for fut in self.queue:
                result = fut.result()
                self.pending.discard(fut)
                fut.release()
                nxt = next(self.todo, None)
                if nxt is not None:
                    self._submit(nxt)
                self._note_in_flight(1)
                yield result
                del result
        except KeyboardInterrupt:  # the running chunks stay for stop() to collect
            raise
        except BaseException:
            self.cancel()
            raise

    def stop(self) -> list[tuple[tuple[int, ...], dict[str, np.ndarray]]]:
        """Stop the run: no new chunk starts, the running ones stop within about a
        second, and the results of every chunk finished (before or now) come back;
        chunks that no worker runs are cancelled at once. Waits at most ``STOP_WAIT_S``
        for the running ones (``distributed.wait`` raises on its timeout: the stop then
        cancelled nothing and lost the finished chunks)."""
        from distributed import Event, wait

        self.todo = iter(())
        held = list(self.pending)
        if not held:
            return []
        event = Event(self.stop_event, client=self.client)
        event.set()
        running = [f for f in held if f.key in self._processing()]
        if running:
            try:
                wait(running, timeout=STOP_WAIT_S)
            except TimeoutError:
                pass  # (the chunks still running are cancelled with the rest)
        results = []
        for f in held:
            if f.status == "finished":
                try:
                    results.append(f.result(timeout=STOP_WAIT_S))
                except Exception:  # noqa: BLE001  (lost with its worker: recomputed later)
                    continue
        self.cancel()
        event.clear()
        return results

    def _processing(self) -> set:
        """Keys of the tasks the workers are running now (a task queued with no worker
        to run it, as with a cluster of none, never finishes: it is not waited for)."""
        try:
            return {k for keys in self.client.processing().values() for k in keys}
        except Exception:  # noqa: BLE001  (a scheduler gone: nothing runs)
            return set()

    def cancel(self) -> None:
        if self.pending:  # stopped early (an error, Ctrl-C, the caller closed us)
            self.client.cancel(list(self.pending))
            self.pending.clear()


def run_distributed(client: Client, tasks: Sequence[ChunkTask], stats: dict | None = None
                    ) -> DistributedRun:
    """The chunks ``tasks`` on ``client``'s workers (see :class:`DistributedRun`)."""
    return DistributedRun(client, tasks, stats)
