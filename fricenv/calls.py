"""How the public calls run their kernels: within a step budget, and stoppable by Ctrl-C.

A kernel holds the interpreter while it runs, so a SIGINT would wait for it to return. A
call that may be long therefore runs its kernel (compiled with ``nogil``) in a worker
thread while the calling thread waits in short joins, where ``KeyboardInterrupt`` arrives.
The kernel reads its budget slot ``W_MAX_STEPS_CALL`` every ``BUDGET_CHECK_STEPS`` steps at
most: on Ctrl-C the waiting thread sets it below 0, the kernel returns within that many
steps, and ``KeyboardInterrupt`` propagates with nothing half-written in the caller's
objects.

Starting a thread costs ~0.1 ms, more than a short call itself. A call first runs in the
calling thread with at most ``DIRECT_STEPS`` steps (~0.05-0.3 s, the Ctrl-C latency there);
one that needs more is run again from its start in the worker, so its result is the one
the kernel computes in one piece. Calls whose scan alone needs more than ``DIRECT_STEPS``
go to the worker at once.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from .checks import check_finite_real
from .core import new_workspace as _new_workspace
from .core.constants import MAX_STEPS_PER_CALL, MAX_STEPS_PER_TAU
from .core.workspace import W_MAX_STEPS_CALL, W_MAX_STEPS_TAU
from .interrupts import sigterm_handled
from .layout import STATUS_STEP_BUDGET

#: Steps a call runs in the calling thread before it is moved to a worker thread.
DIRECT_STEPS = 1e5
#: How often (s) the waiting thread wakes to take a pending KeyboardInterrupt.
JOIN_POLL = 0.1
#: Budget value that ends a running kernel at its next step.
ABORT = -1.0
#: How often (s) a stopping kernel is told again to stop while it is joined.
ABORT_POLL = 0.01


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C, or SIGTERM during a sweep, stopped a run of many cells; ``results`` holds
    every cell finished before it (in the form the interrupted call returns, cells not
    finished marked as not computed) and ``signum`` the signal. A ``KeyboardInterrupt``, so
    that code which stops on Ctrl-C stops on it too. A sweep with a file or store has saved
    its finished cells before this reaches the caller."""

    def __init__(self, results: Any = None, signum: int | None = None) -> None:
        self.signum = signal.SIGINT if signum is None else signum
        super().__init__(f"sweep stopped by {signal.Signals(self.signum).name}")
        self.results: Any = results  # (its form is the interrupted call's)


def _raise_on_sigterm(signum: int, frame: object) -> None:
    raise SweepInterrupted(signum=signum)


@contextlib.contextmanager
def sweep_signals() -> Iterator[None]:
    """Within this block SIGTERM stops a sweep as Ctrl-C does (its finished cells saved,
    then :class:`SweepInterrupted` raised): see :func:`fricenv.interrupts.sigterm_handled`."""
    with sigterm_handled(_raise_on_sigterm):
        yield


def step_budget(max_steps_per_tau: float | None, max_steps: float | None
                ) -> tuple[float, float]:
    """The budget a call runs with: each value as given (a number > 0) or, for None, the
    default (``MAX_STEPS_PER_TAU``, ``MAX_STEPS_PER_CALL``)."""
    out = []
    for name, value, default in (("max_steps_per_tau", max_steps_per_tau, MAX_STEPS_PER_TAU),
                                 ("max_steps", max_steps, MAX_STEPS_PER_CALL)):
        if value is None:
            out.append(default)
            continue
        value = check_finite_real(name, value)
        if value <= 0.0:
            raise ValueError(f"{name} must be > 0, got {value!r}")
        out.append(value)
    return out[0], out[1]


_FRESH = _new_workspace()  # copied: cheaper than filling a new array on every call


def new_workspace(budget: tuple[float, float]) -> np.ndarray:
    """A fresh workspace for one call (see ``core.new_workspace``) with the step budget
    ``budget`` = (steps per unit tau, steps per call)."""
    work = _FRESH.copy()
    work[W_MAX_STEPS_TAU] = budget[0]
    work[W_MAX_STEPS_CALL] = budget[1]
    return work


def run_stoppable(run: Callable[[], object], abort: Callable[[], None],
                  stop_requested: Callable[[], bool] | None = None) -> bool:
    """Run ``run()`` (a ``nogil`` kernel call) in a worker thread while the calling thread
    waits in ``JOIN_POLL`` waits, where signals reach it.

    ``abort()`` tells the running kernel to stop (it lowers a budget slot the kernel reads
    every ``BUDGET_CHECK_STEPS`` steps); it is called again at every poll until the kernel
    has returned, since a kernel may overwrite the slot once in a race with it. When the
    waiting thread gets an exception (``KeyboardInterrupt`` on Ctrl-C, or whatever a signal
    handler raises), the kernel is stopped and waited for, then the exception propagates; a
    second Ctrl-C meanwhile does not cut the wait short, so the caller's arrays are never
    written after this returns. ``stop_requested()``, polled at every wait, stops the kernel
    the same way but returns normally. Returns whether ``run()`` ran to its end unasked;
    an exception raised by ``run()`` itself propagates.

    The wait is on an event the worker sets once ``run()`` has returned, not on
    ``Thread.join``: on Python 3.11 a ``KeyboardInterrupt`` raised inside ``join`` can mark
    a thread that is still running as finished (CPython's bpo-45274 handler releases the
    lock the live thread holds), and the caller would then read arrays the kernel is still
    writing.
    """
    box: dict[str, object] = {}
    returned = threading.Event()

    def target() -> None:
        # (dict.setdefault is atomic: a signal before this line cancels the run instead)
        if box.setdefault("phase", "began") != "began":
            return
        try:
            run()
        except BaseException as error:  # handed to the calling thread
            box["error"] = error
        finally:
            returned.set()

    stopped = False
    try:
        threading.Thread(target=target, name="fricenv-kernel", daemon=True).start()
        while not returned.wait(JOIN_POLL):
            if stop_requested is not None and stop_requested():
                stopped = True
                _stop(returned, abort)
    except BaseException:
        if box.setdefault("phase", "cancelled") == "began":
            _stop(returned, abort)
        raise
    error = box.get("error")
    if isinstance(error, BaseException):
        raise error
    return not stopped


def _stop(returned: threading.Event, abort: Callable[[], None]) -> None:
    """Ask the running kernel to stop until it has returned (``returned`` is set);
    further Ctrl-Cs are dropped."""
    while not returned.is_set():
        try:
            abort()
            returned.wait(ABORT_POLL)
        except KeyboardInterrupt:
            continue


def _in_worker(run: Callable[[np.ndarray], int], work: np.ndarray) -> int:
    """``run(work)`` through :func:`run_stoppable`; Ctrl-C sets the budget slot to
    ``ABORT``."""
    box: dict[str, int] = {}

    def call() -> None:
        box["status"] = run(work)

    def abort() -> None:
        work[W_MAX_STEPS_CALL] = ABORT

    run_stoppable(call, abort)
    return box["status"]


def run_call(run: Callable[[np.ndarray], int], make_work: Callable[[], np.ndarray],
             expected_steps: float) -> int:
    """Run a kernel call: ``run(work)`` starts the call from its inputs (resetting the
    state and statistics it writes) in the workspace ``work`` from ``make_work()`` and
    returns its status. ``expected_steps``: the steps the call needs at least (its scan)."""
    work = make_work()
    budget = float(work[W_MAX_STEPS_CALL])
    if expected_steps <= DIRECT_STEPS and budget > DIRECT_STEPS:
        work[W_MAX_STEPS_CALL] = DIRECT_STEPS
        status = run(work)
        if status != STATUS_STEP_BUDGET or work[W_MAX_STEPS_CALL] != DIRECT_STEPS:
            return status
        # over DIRECT_STEPS, or over its own per-tau budget: which is not told apart, and
        # the worker finds out at a cost of DIRECT_STEPS steps at most
        work = make_work()  # the caches of the first try are never reused
    elif budget <= DIRECT_STEPS:
        return run(work)
    return _in_worker(run, work)

