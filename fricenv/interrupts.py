"""How a fricenv program reports an interrupt: one line and the shell's status.

Kept in the foundation layer, apart from the command line, so that every program (the
``fricenv`` commands, ``fricenv-reproduce``, ``python -m fricenv.atlas``) reports Ctrl-C
alike without importing the command-line package or numba.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

#: How long (s) a swallowed interrupt waits before it is delivered again: long enough for
#: the C code that swallowed it to return to Python.
REDELIVER_DELAY = 0.02


def interrupted(prog: str, exc: KeyboardInterrupt, where: str = "") -> int:
    """Report a Ctrl-C (or a SIGTERM that stopped a sweep) in one line and return the
    shell's status for it, ``128 + signal`` (130 for Ctrl-C), as ``fricenv train`` does:
    a traceback there says nothing the user does not know. ``where``: what was kept."""
    signum = int(getattr(exc, "signum", signal.SIGINT))
    print(f"{prog}: interrupted ({signal.Signals(signum).name})"
          + (f"; {where}" if where else ""), file=sys.stderr, flush=True)
    return 128 + signum


@contextlib.contextmanager
def sigterm_handled(handler: Callable[[int, Any], None]) -> Iterator[None]:
    """Within this block SIGTERM calls ``handler`` (which raises, so that a sweep or a
    training stops as on Ctrl-C, keeping what it finished), where Python's default would
    end the process at once and lose it. SIGTERM is what ``timeout``, SLURM, ``docker
    stop`` and Kubernetes send. Only in the main thread, and only where SIGTERM has its
    default action: a handler of the caller's own is left alone."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL):
        yield
        return
    signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextlib.contextmanager
def interrupts_redelivered() -> Iterator[None]:
    """Within this block a Ctrl-C (or a handled SIGTERM) that Python had to swallow is
    delivered again, so that it stops the program instead of being lost.

    A signal's exception is raised in whatever Python code the main thread is running.
    When that code is a callback called from C (llvmlite calls one as numba compiles),
    the exception cannot cross the C frames: Python prints "Exception ignored on calling
    ctypes callback function" and carries on, and the program then ran to its end as if
    the key had never been pressed. Here such an exception, reported through
    ``sys.unraisablehook``, sends its signal to the main thread once more, a moment later
    from a timer thread, once the C code has returned. Any other unraisable exception
    goes to the hook that was in place. Nested blocks install nothing more; the block
    ends only after a pending delivery, so that the interrupt is raised inside it."""
    previous = sys.unraisablehook
    if getattr(previous, "_fricenv_redelivers", False):
        yield
        return

    pending: list[threading.Timer] = []

    def hook(unraisable: Any) -> None:
        exc = unraisable.exc_value
        if not isinstance(exc, KeyboardInterrupt):
            previous(unraisable)
            return
        signum = int(getattr(exc, "signum", signal.SIGINT))
        main = threading.main_thread().ident
        assert main is not None
        timer = threading.Timer(REDELIVER_DELAY, signal.pthread_kill, (main, signum))
        timer.daemon = True
        timer.start()
        pending.append(timer)

    hook._fricenv_redelivers = True  # type: ignore[attr-defined]
    sys.unraisablehook = hook
    try:
        yield
        for timer in pending:
            timer.join()  # (the signal's exception is raised here, in the block)
    finally:
        sys.unraisablehook = previous
