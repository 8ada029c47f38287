"""Curvature proofs: a step holds no switch, or at most one extremum.

A step is halved until one of these holds, so no dip of v to V can hide between two
extrema of a long step; each proof is a bound, never a sample.
"""

import math

from ..jit import kernel
from ..layout import ST_V_MAX, ST_V_MIN
from .constants import MIN_SPLIT
from .workspace import C_GDD, C_XFS, W_SKIP_EXTREMA


@kernel
def _stays_positive(k0, d0, k1, d1, L, M):
    """Proof that k > 0 on [0, L] from k, k' at both ends and a bound M on |k''|.

    k lies above both k0 + d0 t - M t^2 / 2 and k1 - d1 (L - t) - M (L - t)^2 / 2. The
    larger of these concave bounds is smallest at an end or where they cross (their
    difference is linear in t), so one evaluation decides. False means "not proven".
    """
    if not (k0 > 0.0 and k1 > 0.0 and M < math.inf):
        return False
    slope = d0 - d1 - M * L
    if slope == 0.0:
        return True
    t = -(k0 - k1 + d1 * L + 0.5 * M * L * L) / slope
    if not (0.0 < t < L):
        return True
    return k0 + t * (d0 - 0.5 * M * t) > 0.0

@kernel
def _sign_kept(k0, k1, L, M):
    """Proof that k keeps one strict sign on [0, L] from its end values and |k'| <= M."""
    if k0 > 0.0 and k1 > 0.0:
        return k0 + k1 > M * L
    if k0 < 0.0 and k1 < 0.0:
        return -(k0 + k1) > M * L
    return False

@kernel
def _one_extremum_at_most(h0, d0, h1, d1, hdd0, hdd1, L, M2, M3, cap):
    """May a slip step [0, L] go to the contact search, which handles one extremum of h?

    Yes if h = sd (v - V) provably stays positive (no contact at all), or h' provably
    keeps its sign (h monotone: no extremum), or h'' does (h' monotone: one extremum at
    most), or the step is already tiny. Otherwise the caller halves the step, so no dip
    of h to 0 can hide between two extrema, however long the scan step.
    """
    return (_stays_positive(h0, d0, h1, d1, L, M2) or _monotone(d0, hdd0, d1, hdd1, L, M3)
            or _sign_kept(hdd0, hdd1, L, M3) or L <= MIN_SPLIT * cap)

@kernel
def _monotone(d0, dd0, d1, dd1, L, M):
    """Proof that a function keeps a monotone course on [0, L]: its derivative (d0, d1 at
    the ends, with derivatives dd0, dd1 and |third derivative| <= M) keeps one sign. The
    usual case at a contact, where a step that ends past the switch would otherwise be
    halved."""
    return _stays_positive(d0, dd0, d1, dd1, L, M) or _stays_positive(-d0, -dd0, -d1, -dd1,
                                                                     L, M)

@kernel
def _v_one_extremum(a0, j0, a1, j1, L, m3):
    """Proof that v has at most one extremum on [0, L]: v' keeps its sign, or v'' does
    (v' monotone), given v', v'' at both ends and |v'''| <= m3."""
    s = 1.0 if a0 + a1 >= 0.0 else -1.0
    return _stays_positive(s * a0, s * j0, s * a1, s * j1, L, m3) or _sign_kept(j0, j1, L, m3)

@kernel
def _extremum_matters(cx, stats, sd, v0, v1, a0, a1, L, V, vdd_max):
    """Can the interior extremum of v on this step change v's extrema or touch v = V?

    acc goes from a0 to a1 through 0, so |v - v(end)| <= max(|a0|, |a1|) L on a step whose
    acceleration is monotone; a factor 2 covers the mild non-monotonicity a short step
    allows. A touch is ruled out for certain when ``vdd_max`` (a bound on |v''| over the
    step, inf if unknown) proves sd (v - V) > 0 throughout.
    """
    reach = 2.0 * max(abs(a0), abs(a1)) * L
    top = max(v0, v1) + reach
    bottom = min(v0, v1) - reach
    if cx[W_SKIP_EXTREMA] != 1.0 and (top > stats[ST_V_MAX] or bottom < stats[ST_V_MIN]):
        return True
    if not bottom <= V <= top:
        return False
    return not _stays_positive(sd * (v0 - V), sd * a0, sd * (v1 - V), sd * a1, L, vdd_max)

@kernel
def _stick_held(cx, L, f0, fd0, f1, fd1):
    """Proof that |f| <= xfs holds on a whole stick step [0, L] (f'' = g'' in stick)."""
    xfs = cx[C_XFS]
    M = cx[C_GDD]
    return _stays_positive(xfs - f0, -fd0, xfs - f1, -fd1, L, M) and _stays_positive(
        xfs + f0, fd0, xfs + f1, fd1, L, M)
