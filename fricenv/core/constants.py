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
# their sum loses digits: over tau = 60 at lam = 0, the max |x| error is 9e-13 at a gain
# 1 / sqrt(d2) of 500, 6e-11 at 5e3 and 1e-9 at 5e4 (and a gain of 1e15, one ulp off
# resonance, makes rounding noise look like chattering). Past this gain the exact method
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

# A whole call in one closed-form step (see ``whole_interval``): the damped part must
# oscillate (p^2 >= I_P2_MIN, so 1 / p stays tame).
I_P2_MIN = 0.01
I_MARGIN = 1e-12  # clearance the proofs demand, relative to the size of the terms

# A slip step is stiff when |df/dv| h exceeds this: the Taylor steps' length is then set by
# their stability (the error control holds them near its limit), not by accuracy.
STIFF_HK = 2.5
# Most Taylor steps between Rosenbrock retries in a stiff stretch where they keep failing
ROS_BACKOFF_MAX = 64.0

# Step budget of a call (the workspace's W_MAX_STEPS_TAU and W_MAX_STEPS_CALL start at these;
# callers may set their own): at most MAX_STEPS_PER_TAU steps in each unit of tau, counted in
# consecutive windows from the call's start, and MAX_STEPS_PER_CALL in the call, else the call
# ends with STATUS_STEP_BUDGET. Ordinary runs take at most ~1e4 steps in a unit of tau (stiff
# cubic slip with b1 = b3 = 1e6 included), and a step costs 0.1-3 us, so a call over budget
# ends within about a second (u0 = 1e10 with Taylor steps throughout, at ~2e6 steps in a unit
# of tau, is over it). A call takes at most 1e7 steps, a few seconds at the slowest step
# measured (stiff slip with lam = 1e6: 1e7 steps in 3-4 s), and more only when its caller
# raises the budget: the paper's runs take ~1e4 steps, a regime-map cell ~1e5.
MAX_STEPS_PER_TAU = 1e6
MAX_STEPS_PER_CALL = 1e7
# A unit window may also take this many times the scan's own steps (1 / scan cap), so that
# a plant whose fast tone or damping alone needs more steps than MAX_STEPS_PER_TAU (which
# check_scan_steps admits) is not over budget: slip steps are at most twice the scan cap.
SCAN_ALLOWANCE = 2.0
# The runners compare their step count with the budget at most this many steps apart (one
# compare a step in between): a call lowered to a budget of 0 from another thread ends
# within that many steps (well under a millisecond).
BUDGET_CHECK_STEPS = 256.0
# Time resolution of a call, relative to max(1, |t|) (t runs from 0 in each call): a call
# whose remaining span is below it ends, a Taylor step is never shorter than it, and an
# output instant this close past a step's end belongs to that step.
TIME_REL_TOL = 1e-13
# Output instants and interval lengths that differ by less than this fraction are the same.
GRID_REL_TOL = 1e-12
# A step count whose quotient is within this of a whole number is that number (ceil of a
# quotient such as 10 / 0.1 must not round 100.00000000000001 up to 101).
COUNT_SLACK = 1e-9
# Keeps a tolerance positive where everything it scales with is 0 (a bracket at t = 0, a
# tolerance of 0): the smallest normal double's neighbourhood, far below any real scale.
TINY = 1e-300
# A Taylor step's error target never falls below this share of the state's size: doubles
# resolve nothing finer, and a smaller target would shrink the step to nothing.
TAYLOR_EPS_FLOOR = 1e-16
# Length of the "last Taylor step" before the first one is taken (only the stiffness test
# reads it, against the scan cap).
TAYLOR_FIRST_STEP = 0.05
# The event method carries the tones' cos/sin from step to step by rotation; after this
# many steps they are recomputed from the phase angles, so rounding cannot accumulate.
PHASE_RESYNC_STEPS = 64
# The displacement extremum search is skipped when |v| max * step cannot reach past the
# recorded extrema; this factor covers the rounding of that bound.
REACH_SLACK = 1.0000001
# Below these, a series replaces the direct formula: p^2 tau^2 in the homogeneous transition
# (avoids dividing by p), |s|^2 in E(s) = (e^s - 1) / s (avoids cancellation in e^s - 1).
HOMOG_SERIES_MAX = 1e-2
E1_SERIES_MAX_R2 = 1e-4
# Rosenbrock step-size control: the next step is h * min(ROS_GROW_MAX, max(ROS_SHRINK_MIN,
# ROS_SAFETY * err^(-1/8))), err floored at ROS_ERR_FLOOR (an exact step grows, not
# divides by 0).
ROS_GROW_MAX = 4.0
ROS_SHRINK_MIN = 0.2
ROS_SAFETY = 0.9
ROS_ERR_FLOOR = 1e-30
# Damping from which the closed form runs a plant whatever its tones: d2 = (1 - w^2)^2 +
# (lam w)^2 < 1 / CLOSED_FORM_MAX_GAIN^2 needs |1 - w^2| < 1 / CLOSED_FORM_MAX_GAIN, so
# w^2 > 1 - 1 / CLOSED_FORM_MAX_GAIN, and lam w < 1 / CLOSED_FORM_MAX_GAIN; twice the lam
# that allows leaves a margin for rounding.
LAM_CONDITIONED = 2.0 / (CLOSED_FORM_MAX_GAIN * (1.0 - 1.0 / CLOSED_FORM_MAX_GAIN) ** 0.5)
