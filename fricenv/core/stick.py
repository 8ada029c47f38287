"""The exact stick step, shared by both runners: its length and when |f| first exceeds x_fs.

In stick the block rides the belt (x = x_a + V tau) and f = -lam V - x + g(tau) is known in
closed form, so a stick step is exact whatever the friction law. A step is halved until a
proof shows that |f| <= x_fs holds on all of it or that f has at most one extremum there
(``_stick_trial``); ``_stick_exit_time`` then finds the first instant |f| passes x_fs.
"""

import math

from ..jit import kernel
from .closed_form import _forcing, _rotate, _rotate_by, _stick_at
from .constants import MIN_SPLIT
from .contacts import _force_tie
from .proofs import _monotone, _sign_kept, _stick_held
from .roots import K_STICK_F, _extremum_closed, _root_closed
from .trig import _renorm
from .workspace import C_C1A, C_C2A, C_GDDD, C_LAM, C_S1A, C_S2A, C_V, C_XA, C_XFS


@kernel
def _stick_start(cx, x, c1, s1, c2, s2):
    """Start a stick step at x with tone phases (c_i, s_i); f, f', f'' there."""
    cx[C_XA] = x
    cx[C_C1A] = c1
    cx[C_S1A] = s1
    cx[C_C2A] = c2
    cx[C_S2A] = s2
    V = cx[C_V]
    g0, gd0, gdd0 = _forcing(cx, c1, s1, c2, s2)
    return -cx[C_LAM] * V - x + g0, -V + gd0, gdd0


@kernel
def _stick_trial(cx, L, cap, on_grid, rot, monotone, f0, fd0, fdd0):
    """Length of a stick step from the start in ``cx`` (``_stick_start``; f, f', f''
    there): L, halved until |f| <= x_fs provably holds on the whole step, or f provably has
    one extremum at most (f'' keeps its sign; with ``monotone``, also f' keeping its
    sign), or the step is down to MIN_SPLIT of ``cap``.

    ``on_grid``: a regular scan step of the exact runner, whose tones' rotation ``rot`` =
    (cos, sin, cos, sin) is cached; off the grid (and once halved) the rotation is
    computed. Returns (L, halved, on_grid, held, x, f, f', f'' at the end, the tones'
    cos/sin there).
    """
    x = cx[C_XA]
    V = cx[C_V]
    lam = cx[C_LAM]
    halved = False
    while True:
        if on_grid:
            nc1, ns1, nc2, ns2 = _rotate(cx, rot[0], rot[1], rot[2], rot[3])
            nc1, ns1 = _renorm(nc1, ns1)
            nc2, ns2 = _renorm(nc2, ns2)
        else:
            nc1, ns1, nc2, ns2 = _rotate_by(cx, L)
        x1 = x + V * L
        g1, gd1, gdd1 = _forcing(cx, nc1, ns1, nc2, ns2)
        f1 = -lam * V - x1 + g1
        fd1 = -V + gd1
        held = _stick_held(cx, L, f0, fd0, f1, fd1)
        m3 = cx[C_GDDD]  # bounds |f'''| = |g'''|
        if (held or (monotone and _monotone(fd0, fdd0, fd1, gdd1, L, m3))
                or _sign_kept(fdd0, gdd1, L, m3) or L <= MIN_SPLIT * cap):
            break
        L *= 0.5
        halved = True
        on_grid = False
    return L, halved, on_grid, held, x1, f1, fd1, gdd1, nc1, ns1, nc2, ns2


@kernel
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
        t_ext = _extremum_closed(cx, K_STICK_F, 0.0, L, fd0, fd1, fdd0, fdd1, math.nan, math.nan)
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
                    te = _root_closed(cx, K_STICK_F, off, 0.0, t_ext, f0 - off, f_ext - off, fd0,
                               0.0, fdd0, fdd_ext)
            elif side * f1 > xfs:  # f turns back towards this side and crosses after
                if side * f_ext > xfs:  # (a held tie that turns before it clears xfs)
                    te = t_ext
                else:
                    te = _root_closed(cx, K_STICK_F, off, t_ext, L, f_ext - off, f1 - off, 0.0,
                               fd1, fdd_ext, fdd1)
        elif side * f1 > xfs and not held_tie:
            te = _root_closed(cx, K_STICK_F, off, 0.0, L, f0 - off, f1 - off, fd0, fd1, fdd0, fdd1)
        if te >= 0.0 and (best < 0.0 or te < best):
            best = te
    return best
