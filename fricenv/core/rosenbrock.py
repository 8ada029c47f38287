"""Rosenbrock steps for stiff slip stretches of a stats-only event run.

Shampine's L-stable Rosenbrock pair of order 4(3) (the "stiff" method of Numerical Recipes):
stages Y_i = y + sum a_ij g_j at t + alpha_i h, (I / (gamma h) - J) g_i = f(Y_i) +
gamma_i h f_t + sum c_ij g_j / h; 3 function values and 4 linear solves a step.
"""

from ..friction import kernels as friction
from ..jit import kernel
from .slip import NO_FORCING, _acc, _end_phases, _step_inputs
from .trig import _sincos
from .workspace import C_W1, C_W2

_RG = 0.5
_RA21, _RA31, _RA32 = 2.0, 48.0 / 25.0, 6.0 / 25.0
_RC21, _RC31, _RC32 = -8.0, 372.0 / 25.0, 12.0 / 5.0
_RC41, _RC42, _RC43 = -112.0 / 125.0, -54.0 / 125.0, -2.0 / 5.0
_RB1, _RB2, _RB3, _RB4 = 19.0 / 9.0, 1.0 / 2.0, 25.0 / 108.0, 125.0 / 108.0
_RE1, _RE2, _RE4 = 17.0 / 54.0, 7.0 / 36.0, 125.0 / 108.0
_RG1, _RG2, _RG3, _RG4 = 1.0 / 2.0, -3.0 / 2.0, 121.0 / 50.0, 29.0 / 250.0
_RALPHA3 = 3.0 / 5.0

@kernel
def _ros_solve(c, j22, r1, r2):
    """(c I - J) z = r for J = [[0, 1], [-1, j22]]."""
    det = 1.0 + c * (c - j22)
    z1 = (r2 + (c - j22) * r1) / det
    return z1, c * z1 - r1

@kernel
def _ros4_step(cx, sd, x0, v0, a0, h):
    """One Rosenbrock step of the slip equation from (x0, v0) (phases in cx).

    Returns x, v and v' at the end and the embedded error of x and v. J is exact: the
    friction law's slope enters only dv'/dv. cos/sin of the tone phases at the step end go
    to cx[C_CE1..C_SE2], as after a Taylor step.
    """
    lam, V, xfk, law, lc, u1, u2, cp1, sp1, cp2, sp2 = _step_inputs(cx, sd)
    w1 = cx[C_W1]
    w2 = cx[C_W2]
    j22 = friction.net_slope(law, lc, lam, sd, v0 - V)
    gt = -(u1 * w1 * sp1 + u2 * w2 * sp2)  # dg/dt at the step start
    c = 1.0 / (_RG * h)
    ce1, se1 = _sincos(w1 * h)
    ce2, se2 = _sincos(w2 * h)
    c_end1, c_end2 = _end_phases(cx, (cp1, sp1, cp2, sp2), (ce1, se1, ce2, se2))
    c31, s31 = _sincos(w1 * _RALPHA3 * h)
    c32, s32 = _sincos(w2 * _RALPHA3 * h)
    g_end = u1 * c_end1 + u2 * c_end2
    g_3 = u1 * (cp1 * c31 - sp1 * s31) + u2 * (cp2 * c32 - sp2 * s32)
    g1x, g1v = _ros_solve(c, j22, v0, a0 + h * _RG1 * gt)
    x2 = x0 + _RA21 * g1x
    v2 = v0 + _RA21 * g1v
    f2v = _acc((lam, V, xfk), law, lc, sd, (x2, v2), NO_FORCING) + g_end
    g2x, g2v = _ros_solve(c, j22, v2 + _RC21 * g1x / h,
                          f2v + h * _RG2 * gt + _RC21 * g1v / h)
    x3 = x0 + _RA31 * g1x + _RA32 * g2x
    v3 = v0 + _RA31 * g1v + _RA32 * g2v
    f3v = _acc((lam, V, xfk), law, lc, sd, (x3, v3), NO_FORCING) + g_3
    g3x, g3v = _ros_solve(c, j22, v3 + (_RC31 * g1x + _RC32 * g2x) / h,
                          f3v + h * _RG3 * gt + (_RC31 * g1v + _RC32 * g2v) / h)
    g4x, g4v = _ros_solve(c, j22, v3 + (_RC41 * g1x + _RC42 * g2x + _RC43 * g3x) / h,
                          f3v + h * _RG4 * gt + (_RC41 * g1v + _RC42 * g2v + _RC43 * g3v) / h)
    x1 = x0 + _RB1 * g1x + _RB2 * g2x + _RB3 * g3x + _RB4 * g4x
    v1 = v0 + _RB1 * g1v + _RB2 * g2v + _RB3 * g3v + _RB4 * g4v
    ex = _RE1 * g1x + _RE2 * g2x + _RE4 * g4x
    ev = _RE1 * g1v + _RE2 * g2v + _RE4 * g4v
    a1 = _acc((lam, V, xfk), law, lc, sd, (x1, v1), NO_FORCING) + g_end
    return x1, v1, a1, ex, ev
