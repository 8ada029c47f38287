"""Index layout of the small float64 arrays the numba kernels exchange.

Kept apart from the kernels so that sweeps, environments and tests can name slots without
importing numba code.
"""

# State vector S (length N_STATE): time, displacement, velocity, mode, tone phases.
# mode: -1 slip below belt speed, 0 stick, +1 slip above. Tone i is u_i * cos(phase_i);
# phases are accumulated (phase_i += omega_i * dt) and wrapped to [0, 2 pi), so a change of
# frequency between calls never makes the force jump.
S_T, S_X, S_V, S_MODE, S_PHI1, S_PHI2 = range(6)
N_STATE = 6

# Statistics accumulated by a run (length N_STATS); reset them with core.reset_stats.
ST_DURATION = 0  # time covered
ST_STICK_TIME = 1  # time spent stuck
ST_N_STICK = 2  # slip -> stick transitions (stick phases entered)
ST_N_SLIP = 3  # stick -> slip transitions
ST_N_REVERSAL = 4  # direct slip -> slip reversals through v = V without sticking
ST_V_MAX = 5  # velocity extrema, located exactly (not sampled)
ST_V_MIN = 6
ST_X_MAX = 7  # displacement extrema, located exactly
ST_X_MIN = 8
ST_VR2_INT = 9  # integral of (v - V)^2 dt
ST_N_STEPS = 10  # integrator / scan steps taken (work measure)
N_STATS = 11

# Integration methods.
METHOD_EXACT = 0
METHOD_EVENT = 1
METHOD_RK4 = 2
METHODS = {"exact": METHOD_EXACT, "event": METHOD_EVENT, "rk4": METHOD_RK4}

# Kernel return codes.
STATUS_OK = 0
STATUS_EVENT_CAP = 1  # more events than the cap allows: chattering / Zeno-like run
STATUS_NONFINITE = 2  # the state became NaN or infinite
STATUS_BUFFER_FULL = 3  # trajectory kernel: event buffer full (the wrapper grows it)
STATUS_TOO_STIFF = 4  # slip stiffer than the smallest step the time resolution allows can follow
# Set by the Python wrappers, never by a kernel: the motion ran away (a statistic or the state
# non-finite, or beyond the bound of fricenv.divergence) while the kernel reported OK.
STATUS_DIVERGED = 5
# The call took more steps than its budget allows (the workspace's W_MAX_STEPS_TAU steps in a
# unit of tau, or W_MAX_STEPS_CALL in the call): slip far stiffer than the model's O(1) scale,
# or a state far from it. The Python wrappers also use it when a call is stopped on request.
STATUS_STEP_BUDGET = 6

# Event kinds in a trajectory.
EVENT_STICK = 1  # slip -> stick
EVENT_SLIP = 2  # stick -> slip
EVENT_REVERSAL = 3  # slip -> opposite slip, no stick
