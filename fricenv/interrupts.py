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
