"""Hear numba compile fricenv's kernels: announce the first compile, sum the seconds.

numba fires its ``numba:compile`` event around every compile, and only on a cache miss (a
kernel loaded from the cache fires none). :func:`listen` (called once, when
:mod:`fricenv.jit` is imported, before any kernel can compile) registers a listener that

- at the start of an outermost compile of a fricenv kernel, hands its dispatcher to
  :data:`on_compile` (``import fricenv`` sets it to
  ``fricenv.compile_notice.compile_starting``, which prints the compile notice once per
  workload and process);
- at the end of any outermost compile, adds its seconds to :func:`compile_seconds`, which
  :mod:`fricenv.progress` leaves out of its bars' rates.

This module imports nothing of the package: :mod:`fricenv.jit` imports it, while the
notice, above the kernels, registers itself here (the kernels know nothing of it). numba
compiles under one global lock, so the nesting depth is one counter. A failing notice is
logged at DEBUG and swallowed: it never stops a call.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

_log = logging.getLogger(__name__)

#: Called with the dispatcher of each outermost compile of a fricenv kernel, as it starts.
on_compile: Callable[[Any], None] | None = None


class _Counter:
    """The listener's state and behaviour (the numba base class is added by :func:`listen`,
    so that importing this module does not import numba)."""

    def __init__(self) -> None:
        self.depth = 0
        self.started = 0.0
        self.seconds = 0.0

    def on_start(self, event: Any) -> None:
        self.depth += 1
        if self.depth != 1:
            return
        self.started = time.perf_counter()
        try:
            dispatcher = event.data["dispatcher"]
            if on_compile is not None and getattr(
                    dispatcher.py_func, "__module__", "").startswith("fricenv."):
                on_compile(dispatcher)
        except Exception as e:  # (another numba's event data, a notice that failed)
            _log.debug("compile notice failed: %r", e)

    def on_end(self, event: Any) -> None:
        self.depth = max(0, self.depth - 1)
        if self.depth == 0:
            self.seconds += time.perf_counter() - self.started


_listener: _Counter | None = None


def listen(event: Any) -> None:
    """Register the listener with numba's event module ``numba.core.event`` (once per
    process; :mod:`fricenv.jit`, which imports numba, passes it)."""
    global _listener
    if _listener is not None:
        return

    class Listener(_Counter, event.Listener):  # (numba checks the base class)
        pass

    _listener = Listener()
    event.register("numba:compile", _listener)


def compile_seconds() -> float:
    """Seconds this process has spent compiling numba functions (fricenv's or others',
    their outermost compiles) since :func:`listen`."""
    return 0.0 if _listener is None else _listener.seconds
