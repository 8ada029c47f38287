"""Contacts of slip with v = V, and what follows them (stick or reversal)."""

from ..friction import kernels as friction
from ..jit import kernel
from ..layout import EVENT_REVERSAL, EVENT_STICK, ST_N_REVERSAL, ST_N_SLIP, ST_N_STICK
from .constants import GRAZE_REL
from .workspace import C_LAM, C_LAW, C_U1, C_U2, C_V, C_W1, C_W2, C_XFK, C_XFS


@kernel
def _start_slope(cx, fresh, h0, d0, x, v):
    """h' at a slip step's start, for the contact search.

    A phase that starts on the switching surface (``fresh``, h0 <= 0) leaves stick or
    reverses with h' = |f| - F(0+) >= x_fs - F(0+) >= 0 (F(0+) is x_fk for a law that
    jumps to its kinetic level, x_fs for one continuous at break-away, where h' starts
    at 0), so a negative h' there within the rounding of the acceleration's terms is
    taken as 0. A larger negative one (a given
    state, or an excitation retuned between calls) heads to the other side at once and is
    kept: the contact is then at the start (clamped to 0 too, a dip of h below 0 that comes
    back within the step would go unseen: slip on with v past V, status OK).
    """
    if fresh and h0 <= 0.0 and d0 < 0.0:
        level = friction.start_level(cx[C_LAW], cx[C_XFK], cx[C_XFS])
        noise = GRAZE_REL * (
            abs(cx[C_LAM] * v) + abs(x) + level + abs(cx[C_U1]) + abs(cx[C_U2]))
        if d0 >= -noise:
            return 0.0
    return d0

#: ``_unresolved_return``'s answer where h is resolved (the contact search goes on)
_RESOLVED = -2.0

@kernel
def _unresolved_return(L, h0, d0, q0, h1, tol):
    """Contact time of a slip step that starts on the switching surface heading off it while
    h = sd (v - V) never reads above rounding (``tol``): -1 (no contact in the step) or
    the time h returns to 0; ``_RESOLVED`` where that does not apply.

    Leaving stick with x_fs = x_fk (h' = 0, h'' > 0), or reversing just past the static
    level (h' tiny, h'' < 0), h stays within a few ulps of 0 for a while: its computed
    values are rounding noise. Reading a contact at the start from them ended each new
    phase where it began, without time moving, until the event cap stopped the run as
    "chattering"; a root search on them placed the return up to 30 % of the excursion
    off. The derivatives are resolved: near the start h = d0 t + q0 t^2 / 2 + O(t^3), so
    h rises and comes back (q0 < 0) at -2 d0 / q0, where the contact is taken (the state
    there differs from the excursion's by rounding only).
    """
    if not (abs(h0) <= tol and (d0 > 0.0 or (d0 == 0.0 and q0 > 0.0))):
        return _RESOLVED
    if q0 < 0.0:
        back = -2.0 * d0 / q0
        if back < L:
            return back
        return -1.0 if h1 >= -tol else L
    return -1.0 if h1 >= -tol else _RESOLVED

@kernel(takes_kernels=True)
def _contact_time(root, cx, kind, L, start, end, ext):
    """First relative time in (0, L] where h = sd (v - V) reaches 0, or -1 (0: at once).

    ``root`` is the step's family's root search (``_root_closed`` or ``_root_dense``).
    ``start`` and ``end`` are (h, h', h'') at 0 and L; ``ext`` = (t_ext, h_ext, q_ext)
    the interior extremum of h (t_ext < 0: none) and h'' there (the h'' place the root
    search's first point). A phase
    that starts on the switching surface (h0 = 0, d0 clamped to >= 0 by the caller) only
    ends once h has been positive, or where ``_unresolved_return`` says when it never
    rises above rounding.
    """
    h0, d0, q0 = start
    h1, d1, q1 = end
    t_ext, h_ext, q_ext = ext
    tol = GRAZE_REL * max(1.0, abs(cx[C_V]))
    if t_ext >= 0.0 and d0 > 0.0:  # h rises to a maximum, then falls
        if h1 <= 0.0:
            if h_ext <= tol:
                te = _unresolved_return(L, h0, d0, q0, h1, tol)
                if te != _RESOLVED:
                    return te
                if h_ext <= 0.0:
                    return 0.0
            return root(cx, kind, 0.0, t_ext, L, h_ext, h1, 0.0, d1, q_ext, q1)
        return -1.0
    if t_ext >= 0.0 and d0 < 0.0:  # h falls to a minimum (grazing if it only touches 0)
        if h_ext <= 0.0:
            if h0 <= 0.0:
                return 0.0
            return root(cx, kind, 0.0, 0.0, t_ext, h0, h_ext, d0, 0.0, q0, q_ext)
        # a minimum within rounding of 0 is a touch: which side of 0 the computed value
        # lands on is an accident of the last bit
        if h_ext <= tol:
            return t_ext
        return -1.0
    if h1 <= 0.0:
        if h0 <= 0.0:
            te = _unresolved_return(L, h0, d0, q0, h1, tol)
            return 0.0 if te == _RESOLVED else te
        return root(cx, kind, 0.0, 0.0, L, h0, h1, d0, d1, q0, q1)
    return -1.0

@kernel
def _force_tie(cx, x):
    """How far |f| may pass x_fs and still be taken as x_fs: the rounding of f's terms.

    At a regime boundary a contact lands with |f| = x_fs to the last bits, where the
    computed f falls on either side by accident. Taken as a pass, a falling |f| makes a
    reversal whose slip (h' = |f| - x_fk ~ 0 when x_fs = x_fk) comes back at once to the
    same tie, or a stick left again at once: hundreds of switches ~1e-16 apart, or the
    event cap. A tie with |f| falling sticks, and a stick holds through it.
    """
    return GRAZE_REL * (
        abs(cx[C_LAM] * cx[C_V]) + abs(x) + abs(cx[C_U1]) + abs(cx[C_U2]))

@kernel
def _contact_outcome(cx, stats, x, c1, s1, c2, s2, sd):
    """Mode after slip in direction sd reaches v = V at x (tone phases c_i = cos, s_i =
    sin): stick, or reverse."""
    f = -cx[C_LAM] * cx[C_V] - x + cx[C_U1] * c1 + cx[C_U2] * c2
    excess = abs(f) - cx[C_XFS]
    if excess > 0.0 and excess <= _force_tie(cx, x):
        fd = -cx[C_V] - cx[C_U1] * cx[C_W1] * s1 - cx[C_U2] * cx[C_W2] * s2
        if f * fd <= 0.0:  # |f| not rising
            excess = 0.0
    if excess <= 0.0:
        stats[ST_N_STICK] += 1.0
        return 0.0, EVENT_STICK
    stats[ST_N_REVERSAL] += 1.0
    return (1.0 if f > 0.0 else -1.0), EVENT_REVERSAL

@kernel
def _stick_outcome(cx, stats, x, c1, c2):
    f = -cx[C_LAM] * cx[C_V] - x + cx[C_U1] * c1 + cx[C_U2] * c2
    stats[ST_N_SLIP] += 1.0
    return 1.0 if f > 0.0 else -1.0
