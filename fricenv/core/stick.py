"""The exact stick phase: when |f| first exceeds x_fs."""

import math

from ..jit import kernel
from .closed_form import _stick_at
from .contacts import _force_tie
from .roots import K_STICK_F, _extremum, _root
from .workspace import C_XA, C_XFS


@kernel(inline=True)
def _stick_exit_time(cx, L, f0, fd0, fdd0, f1, fd1, fdd1):
    """First relative time in [0, L] where |f| exceeds xfs during a stick, or -1.

    Each side (f > xfs, f < -xfs) is checked on the monotone pieces of f, split at the
    interior extremum of f when f' changes sign, so a peak of |f| inside the step that
    pokes past xfs is not missed. The caller makes sure f has one extremum at most.
    """
    xfs = cx[C_XFS]
    t_ext = -1.0
    f_ext = 0.0
    fdd_ext = 0.0
    if fd0 * fd1 < 0.0:
        t_ext = _extremum(cx, K_STICK_F, 0.0, L, fd0, fd1, fdd0, fdd1, math.nan, math.nan)
        _, f_ext, _, fdd_ext = _stick_at(cx, t_ext)
    best = -1.0
    tie = _force_tie(cx, cx[C_XA])
    for side in (1.0, -1.0):
        off = side * xfs  # the root searched is f = off; violated where side * f > xfs
        # past xfs at the start: leave now, unless by rounding only with |f| falling
        # (see _force_tie), which holds as f = off
        held_tie = side * f0 > xfs and side * f0 - xfs <= tie and side * fd0 <= 0.0
        if side * f0 > xfs and not held_tie:
            return 0.0
        te = -1.0
        if t_ext >= 0.0:
            if side * fd0 > 0.0:  # f heads to this side first and turns inside the step
                if side * f_ext > xfs:
                    te = _root(cx, K_STICK_F, off, 0.0, t_ext, f0 - off, f_ext - off, fd0,
                               0.0, fdd0, fdd_ext)
            elif side * f1 > xfs:  # f turns back towards this side and crosses after
                if side * f_ext > xfs:  # (a held tie that turns before it clears xfs)
                    te = t_ext
                else:
                    te = _root(cx, K_STICK_F, off, t_ext, L, f_ext - off, f1 - off, 0.0,
                               fd1, fdd_ext, fdd1)
        elif side * f1 > xfs and not held_tie:
            te = _root(cx, K_STICK_F, off, 0.0, L, f0 - off, f1 - off, fd0, fd1, fdd0, fdd1)
        if te >= 0.0 and (best < 0.0 or te < best):
            best = te
    return best
