"""The friction laws inside the kernels: one entry per question, dispatched on the law's code.

The solvers call these and never a law's module directly (those called from one place in
a step loop are inlined there at numba's IR level, so that LLVM sees the law's branch and
takes it out of the loop), so a law joins every kernel by
a branch here (its ``CODE``), and its module holds the mathematics, as plain Python
functions that this module compiles (``QUESTIONS``). The law's constants
travel as a 4-tuple ``lc`` that its ``prepare`` makes from the parameter row's law block
(``params.P_LAW_PARAMS``); ``sd`` is the slip direction (+1 above the belt speed, -1
below) and ``vr = v - V``.
"""

from ..jit import kernel
from . import coulomb, cubic, exponential

COULOMB = float(coulomb.CODE)
CUBIC = float(cubic.CODE)
EXPONENTIAL = float(exponential.CODE)
#: Workspace scratch any law's Taylor recurrence needs (its ``SCRATCH``), in doubles.
LAW_SCRATCH = exponential.SCRATCH

#: The numeric functions each law's module defines, in plain Python (so that naming a law
#: loads no numba); compiled here, in this order.
QUESTIONS = ("prepare", "add_accel", "sgn_accel", "slope", "net_slope", "taylor_term",
             "taylor_step_cap", "tangent_series")


def _compiled(law: object, inline: bool) -> tuple:
    """The law's functions as kernels: inlined (IR level) into their one caller, the branch
    below, where ``inline`` (typed there once either way, they add no compile unit of
    their own: three laws' 21 units added 2.3 s to the first event-method call from an
    empty cache); else compiled apart, so that a law of long functions (exp, pow, loops)
    does not grow the hot loops of the others past what LLVM inlines there."""
    return tuple(kernel(getattr(law, q), called_once=inline) for q in QUESTIONS)


(co_prepare, co_add_accel, co_sgn_accel, co_slope, co_net_slope, co_taylor_term,
 co_taylor_step_cap, co_tangent_series) = _compiled(coulomb, inline=True)
(cu_prepare, cu_add_accel, cu_sgn_accel, cu_slope, cu_net_slope, cu_taylor_term,
 cu_taylor_step_cap, cu_tangent_series) = _compiled(cubic, inline=True)
(ex_prepare, ex_add_accel, ex_sgn_accel, ex_slope, ex_net_slope, ex_taylor_term,
 ex_taylor_step_cap, ex_tangent_series) = _compiled(exponential, inline=False)


_family_code = kernel(cubic.family_code)


@kernel
def polynomial_code(b1, b3):
    """The law of a plant given by b1 and b3 alone (the paper's family): Coulomb where
    both are 0, else cubic (``cubic.family_code``)."""
    return _family_code(b1, b3, COULOMB)


@kernel
def closed_form(law):
    """Whether the ``exact`` method's closed form runs the law (``method_for``, inside the
    kernels)."""
    return law == COULOMB


@kernel
def prepare(law, p0, p1, p2, xfk, xfs):
    """The law's constants ``lc`` from its parameters (p0, p1, p2) and the levels."""
    if law == CUBIC:
        return cu_prepare(p0, p1, p2, xfk, xfs)
    if law == EXPONENTIAL:
        return ex_prepare(p0, p1, p2, xfk, xfs)
    return co_prepare(p0, p1, p2, xfk, xfs)


@kernel(called_once=True)
def add_accel(law, lc, a, sd, vr):
    """``a`` plus the speed-dependent part of the slip acceleration (all of ``-F`` but the
    kinetic level ``-sd xfk``, which the solvers add themselves)."""
    if law == CUBIC:
        return cu_add_accel(a, lc, sd, vr)
    if law == EXPONENTIAL:
        return ex_add_accel(a, lc, sd, vr)
    return co_add_accel(a, lc, sd, vr)


@kernel(called_once=True)
def sgn_accel(law, lc, a, s, vr):
    """``add_accel`` for the RK4 baseline, which takes ``s = sgn(vr)`` literally (0 at vr =
    0) and writes each law as the paper's Eq. 7 does."""
    if law == CUBIC:
        return cu_sgn_accel(a, lc, s, vr)
    if law == EXPONENTIAL:
        return ex_sgn_accel(a, lc, s, vr)
    return co_sgn_accel(a, lc, s, vr)


@kernel
def slope(law, lc, sd, vr):
    """-dF/dvr in slip."""
    if law == CUBIC:
        return cu_slope(lc, sd, vr)
    if law == EXPONENTIAL:
        return ex_slope(lc, sd, vr)
    return co_slope(lc, sd, vr)


@kernel
def net_slope(law, lc, lam, sd, vr):
    """dv'/dv in slip, -lam - dF/dvr: the stiffness of slip and the Rosenbrock Jacobian."""
    if law == CUBIC:
        return cu_net_slope(lc, lam, sd, vr)
    if law == EXPONENTIAL:
        return ex_net_slope(lc, lam, sd, vr)
    return co_net_slope(lc, lam, sd, vr)


@kernel(called_once=True)
def taylor_term(law, lc, sd, cx, at, k, wk):
    """k-th Taylor coefficient of the speed-dependent acceleration along a slip step, from
    the series of w = v - V in ``cx[tw:]`` (``wk`` = its k-th term), ``at`` = (tw, tq,
    tl); ``cx[tq:]`` and ``cx[tl:]`` are the law's scratch. Orders are asked in turn from
    0."""
    if law == CUBIC:
        return cu_taylor_term(lc, sd, cx, at, k, wk)
    if law == EXPONENTIAL:
        return ex_taylor_term(lc, sd, cx, at, k, wk)
    return co_taylor_term(lc, sd, cx, at, k, wk)


@kernel(called_once=True)
def taylor_step_cap(law, lc, cx, tl, n, eps, h):
    """The Taylor step ``h`` of order ``n``, shortened where the law's own series would not
    converge over it at tolerance ``eps``."""
    if law == CUBIC:
        return cu_taylor_step_cap(lc, cx, tl, n, eps, h)
    if law == EXPONENTIAL:
        return ex_taylor_step_cap(lc, cx, tl, n, eps, h)
    return co_taylor_step_cap(lc, cx, tl, n, eps, h)


@kernel(called_once=True)
def tangent_series(law, lc, sd, cx, at, out, n):
    """Taylor coefficients along the current slip step of the speed-dependent
    acceleration's slope (row 0 of ``out``) and of its derivatives by xfk, xfs and the
    law's three parameters (rows 1 .. 5), orders 0 .. n - 1: what the forward
    sensitivities' series need (:mod:`fricenv.core.tangent`). ``at`` = (offset of the
    series of w, offset of the law's scratch) in ``cx``."""
    if law == CUBIC:
        cu_tangent_series(lc, sd, cx, at, out, n)
    elif law == EXPONENTIAL:
        ex_tangent_series(lc, sd, cx, at, out, n)
    else:
        co_tangent_series(lc, sd, cx, at, out, n)


@kernel(called_once=True)
def start_level(law, xfk, xfs):
    """|F| as slip starts (vr -> 0): ``xfs`` for a law continuous at break-away, else the
    kinetic level ``xfk``."""
    if law == EXPONENTIAL:
        return xfs
    return xfk
