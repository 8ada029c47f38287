"""The slip equation for any friction law: acceleration, step inputs, carried phases.

Shared by the Taylor and the Rosenbrock steps of the event method.
"""

import math

from ..friction import kernels as friction
from ..jit import kernel
from .trig import _renorm, _wrap
from .workspace import (
    C_CE1,
    C_CE2,
    C_CP1,
    C_CP2,
    C_LAM,
    C_LAW,
    C_LC,
    C_SE1,
    C_SE2,
    C_SP1,
    C_SP2,
    C_U1,
    C_U2,
    C_V,
    C_W1,
    C_W2,
    C_XFK,
)


# ----------------------------------------------------------------------------------------
# Event-driven runner: Taylor steps in slip, exact stick
# ----------------------------------------------------------------------------------------
@kernel
def _law(cx):
    """The friction law's code and constants ``lc`` (see :mod:`fricenv.friction.kernels`)."""
    return cx[C_LAW], (cx[C_LC], cx[C_LC + 1], cx[C_LC + 2], cx[C_LC + 3])

@kernel
def _rhs_acc(cx, sd, x, v, ph1, ph2):
    """Slip acceleration for any friction law; tone phases given as angles."""
    law, lc = _law(cx)
    return _acc((cx[C_LAM], cx[C_V], cx[C_XFK]), law, lc, sd, (x, v),
                (cx[C_U1], cx[C_U2], ph1, ph2))

#: ``_acc``'s forcing without the tones.
NO_FORCING = (0.0, 0.0, 0.0, 0.0)


@kernel
def _acc(plant, law, lc, sd, state, forcing):
    """Slip acceleration in direction ``sd`` from scalars: ``plant`` = (lam, V, xfk), the
    law's code and constants, ``state`` = (x, v), ``forcing`` = (u1, u2, ph1, ph2)
    (``NO_FORCING``: the tones left out, for a caller that adds them itself); terms a
    configuration zeroes are skipped."""
    lam, V, xfk = plant
    x, v = state
    u1, u2, ph1, ph2 = forcing
    a = -lam * v - x - sd * xfk
    if u1 != 0.0:
        a += u1 * math.cos(ph1)
    if u2 != 0.0:
        a += u2 * math.cos(ph2)
    return friction.add_accel(law, lc, a, sd, v - V)

@kernel
def _set_phases(cx, ph1, ph2):
    """cos/sin of the tone phases at a slip step's start, from the angles."""
    cx[C_CP1] = math.cos(ph1)
    cx[C_SP1] = math.sin(ph1)
    cx[C_CP2] = math.cos(ph2)
    cx[C_SP2] = math.sin(ph2)

@kernel
def _step_inputs(cx, sd):
    """What a Taylor or Rosenbrock slip step reads from the context, as scalars (kept
    in registers: the stages then never reload the array)."""
    law, lc = _law(cx)
    return (cx[C_LAM], cx[C_V], cx[C_XFK], law, lc, cx[C_U1], cx[C_U2],
            cx[C_CP1], cx[C_SP1], cx[C_CP2], cx[C_SP2])

@kernel
def _end_phases(cx, start, rot):
    """Tone phases (cos/sin) at a step's end from its start ``start`` = (cp1, sp1, cp2, sp2)
    and the rotations ``rot`` = (ce1, se1, ce2, se2); stored in cx[C_CE1..C_SE2] for the
    next step. Returns the forcing's cosines there."""
    cp1, sp1, cp2, sp2 = start
    ce1, se1, ce2, se2 = rot
    c_end1 = cp1 * ce1 - sp1 * se1
    c_end2 = cp2 * ce2 - sp2 * se2
    cx[C_CE1] = c_end1
    cx[C_SE1] = sp1 * ce1 + cp1 * se1
    cx[C_CE2] = c_end2
    cx[C_SE2] = sp2 * ce2 + cp2 * se2
    return c_end1, c_end2

@kernel
def _carry(cx, start, end, h):
    """Move to the end of an accepted slip step of length h from ``start`` = (t, phase
    angles) to ``end`` = (x, v, v'): its (t, x, v, v', phases); the end's tone cos/sin
    become the next step's start (renormalised)."""
    t, ph1, ph2 = start
    x1, v1, a1 = end
    cx[C_CP1], cx[C_SP1] = _renorm(cx[C_CE1], cx[C_SE1])
    cx[C_CP2], cx[C_SP2] = _renorm(cx[C_CE2], cx[C_SE2])
    return t + h, x1, v1, a1, _wrap(ph1 + cx[C_W1] * h), _wrap(ph2 + cx[C_W2] * h)
