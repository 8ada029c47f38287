"""Tolerances, floors and caps of the kernels, each defined once.

Every threshold a kernel compares against lives here under a name that says what it bounds;
documentation quotes the name, never the number.
"""

import math

TWO_PI = 2.0 * math.pi

# Scan steps must hold at most one extremum of v (or of f in stick): a tone's extrema are
# pi / omega apart, so half a radian per step leaves a wide margin (>= 12 steps a period).
DELTA_MAX = 0.5  # longest scan step in tau
PHASE_PER_STEP = 0.5  # longest scan step in radians of the fastest active tone
# A caller that reads no extrema (W_SKIP_EXTREMA) needs only the switches, which the curvature
# proofs guard on steps of any length (see _one_extremum_at_most), so its scan steps may be
# longer: a radian of the fastest tone keeps the (v - V)^2 quadrature within ~1e-6 V^2 tau.
DELTA_WIDE = 1.0
PHASE_PER_STEP_WIDE = 1.0
# Steps are halved until the proofs hold, at most down to this fraction of the scan step.
MIN_SPLIT = 1.0 / 1024.0
MAX_ROOT_ITER = 200
# The closed form writes x = x_p + H (x0 - x_p), and a tone's particular amplitude is
# |u| / sqrt(d2), d2 = (1 - w^2)^2 + (lam w)^2. Near resonance both terms are large and
# their sum loses digits: over tau = 60 at lam = 0, the max |x| error was 9e-13 at a gain
# 1 / sqrt(d2) of 500, 6e-11 at 5e3 and 1e-9 at 5e4 (and a gain of 1e15, one ulp off
# resonance, made rounding noise look like chattering). Past this gain the exact method
# hands the call to the event method; exact resonance (d2 = 0) keeps its own closed form.
CLOSED_FORM_MAX_GAIN = 1e3
_D2_MIN = 1.0 / (CLOSED_FORM_MAX_GAIN * CLOSED_FORM_MAX_GAIN)
# Returned by the closed-form runner when a tone is too close to resonance (never leaves
# ``advance_ws`` / ``record``, which then run the event method).
_STATUS_NEAR_RESONANCE = -1
EVENT_REL_TOL = 1e-15  # switching instants: to rounding (a few ulps of the step time)
GRAZE_ULPS = 8.0  # a velocity extremum this many ulps of V short of V still touches it
# ... and this much of a value's terms is its rounding (contacts, ties with x_fs)
GRAZE_REL = GRAZE_ULPS * 2.220446049250313e-16
# An extremum's value is insensitive to its position (error ~ f'' dt^2), so 1e-9 in time
# already gives the value to rounding.
EXTREMUM_REL_TOL = 1e-9

# ----------------------------------------------------------------------------------------
# A whole call in one closed-form step (stats-only callers that read no extrema)
# ----------------------------------------------------------------------------------------
# In slip, v is a damped oscillation plus two sinusoids, so over a call [0, T]:
# * sd (v - V) is bounded below by the sum of each part's own lowest value: a tone's over
#   the arc its phase sweeps (minus its amplitude if the arc passes its trough, else its
#   lower end value), the damped part's from its ends and a bound on its curvature. When
#   that sum stays above 0 there is no contact in the whole call, and one closed-form
#   step covers it however many scan steps the tones' speed would otherwise take.
# * the (v - V)^2 integral is exact: with each part written Re(a_k e^(z_k t)), a product of
#   two parts integrates to T E((z_k + z_l) T) terms, E(s) = (e^s - 1) / s, whose values
#   depend only on (lam, w1, w2, T) and are cached.
# In stick, f = -lam V - x0 - V t + g(t) is bounded against +-xfs the same way.
# Whatever is not proven goes to the scan. The damped part must oscillate (p^2 >= I_P2_MIN,
# so 1 / p stays tame) and no tone may be resonant.
I_P2_MIN = 0.01
I_MARGIN = 1e-12  # clearance the proofs demand, relative to the size of the terms

# A slip step is stiff when |df/dv| h exceeds this: the Taylor steps' length is then set by
# their stability (the error control holds them near its limit), not by accuracy.
STIFF_HK = 2.5
# Most Taylor steps between Rosenbrock retries in a stiff stretch where they keep failing
ROS_BACKOFF_MAX = 64.0
