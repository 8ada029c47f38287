"""How a fricenv program reports an interrupt: one line and the shell's status.

Kept in the foundation layer, apart from the command line, so that every program (the
``fricenv`` commands, ``fricenv-reproduce``, ``python -m fricenv.atlas``) reports Ctrl-C
alike without importing the command-line package or numba.
"""

from __future__ import annotations

import signal
import sys


def interrupted(prog: str, exc: KeyboardInterrupt, where: str = "") -> int:
    """Report a Ctrl-C (or a SIGTERM that stopped a sweep) in one line and return the
    shell's status for it, ``128 + signal`` (130 for Ctrl-C), as ``fricenv train`` does:
    a traceback there says nothing the user does not know. ``where``: what was kept."""
    signum = int(getattr(exc, "signum", signal.SIGINT))
    print(f"{prog}: interrupted ({signal.Signals(signum).name})"
          + (f"; {where}" if where else ""), file=sys.stderr, flush=True)
    return 128 + signum
