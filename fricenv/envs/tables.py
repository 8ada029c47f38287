"""Index layouts of the environments' arrays, each declared once as an ordered list of slots.

The kernels (:mod:`fricenv.envs.kernels`), the scenes (:mod:`fricenv.envs.scenes`) and the
environments name slots from here; offsets are computed by :class:`fricenv.slots.Layout`.
"""

from __future__ import annotations

from fricenv.core.workspace import N_WORK
from fricenv.envs.channels import OBSERVATION
from fricenv.layout import N_STATE, N_STATS
from fricenv.params import N_LAW_PARAMS, N_PARAMS
from fricenv.slots import Layout

# The float64 configuration vector shared by all plants of an environment.
CONFIG = Layout("config")
C_DT = CONFIG.take("C_DT")  # control interval
C_ACTION_MODE, C_INCREMENTAL = CONFIG.group("C_ACTION_MODE", "C_INCREMENTAL")
# excitation bounds and the incremental action's largest steps
C_U_LO, C_U_HI, C_NU_LO, C_NU_HI, C_DU, C_DNU = CONFIG.group(
    "C_U_LO", "C_U_HI", "C_NU_LO", "C_NU_HI", "C_DU", "C_DNU")
C_G1, C_G2 = CONFIG.group("C_G1", "C_G2")  # tone gains (u1 = g1 u0, u2 = g2 u0)
# reward weights and scales, termination limits
C_W_STICK, C_W_VEL, C_W_EFFORT, C_EFFORT_NORM, C_X_LIM, C_V_LIM = CONFIG.group(
    "C_W_STICK", "C_W_VEL", "C_W_EFFORT", "C_EFFORT_NORM", "C_X_LIM", "C_V_LIM")
# the core's method (METHOD_AUTO: by friction law), tolerances and event cap
C_METHOD, C_RTOL, C_ATOL, C_MAX_EVENTS = CONFIG.group(
    "C_METHOD", "C_RTOL", "C_ATOL", "C_MAX_EVENTS")
C_U0_START, C_NU_START = CONFIG.group("C_U0_START", "C_NU_START")  # excitation at reset
# The scene's friction law: -1 for the paper's laws, whose code each episode takes from its
# drawn b1 and b3; otherwise the law's code and its parameters (params.P_LAW_PARAMS order).
C_LAW = CONFIG.take("C_LAW")
C_LAW_P = CONFIG.take("C_LAW_P", N_LAW_PARAMS)
N_CFG = CONFIG.size

# Per-step results (float64): reward, stick fraction, effort, velocity variance, mean of
# v - V, terminated. A single env's ``res`` is one such vector; the batch kernels' ``res``
# is (N_RES, n), a row per result, so the vector env returns each as one contiguous copy.
RESULTS = Layout("results")
R_REWARD, R_STICK, R_EFFORT, R_VAR, R_MEAN_VR, R_TERM = RESULTS.group(
    "R_REWARD", "R_STICK", "R_EFFORT", "R_VAR", "R_MEAN_VR", "R_TERM")
N_RES = RESULTS.size

# The per-episode starting vector (what a reset needs besides the parameters).
INIT = Layout("init")
I_X0, I_V0, I_PHI1, I_PHI2, I_U0, I_NU = INIT.group(
    "I_X0", "I_V0", "I_PHI1", "I_PHI2", "I_U0", "I_NU")
N_INIT = INIT.size

# One episode's uniform draws, consumed in this order (determinism depends on it): the plant
# parameters that may be randomised, then the starting state.
DRAWS = Layout("draws")
D_LAM, D_ETA, D_V, D_XFK, D_XFS, D_B1, D_B3 = DRAWS.group(
    "lam", "eta", "V", "xfk", "xfs", "b1", "b3")
D_X0, D_V0, D_PHI1, D_PHI2 = DRAWS.group("x0", "v0", "phi1", "phi2")
#: Plant parameters that may be randomised per episode or overridden by ``reset(options=...)``.
RANDOMIZABLE = tuple(name for name, _, _ in DRAWS.slots[:D_X0])
#: Starting-state quantities, drawn after the parameters.
INITIAL = tuple(name for name, _, _ in DRAWS.slots[D_X0:])
#: Number of uniform draws one episode consumes, whatever the options or settings.
N_DRAWS = DRAWS.size

# Observation vector: laid out from its channels' declaration (``channels.OBSERVATION``);
# the kernels name its slots by these constants.
OBS = OBSERVATION.layout
O_X, O_VR, O_STICK, O_COS1, O_SIN1, O_COS2, O_SIN2, O_U0, O_NU = (OBS.offsets()[name] for name in (
    "O_X", "O_VR", "O_STICK", "O_COS1", "O_SIN1", "O_COS2", "O_SIN2", "O_U0", "O_NU"))
N_OBS = OBS.size

# Slots of the vector kernel's int64 ``ivars``: three inputs (the parallel kernel's task
# count last) and two counts it writes.
IVARS = Layout("ivars")
IV_MAX_STEPS, IV_MODE, IV_N_RESET, IV_N_EMPTY, IV_N_TASKS = IVARS.group(
    "IV_MAX_STEPS", "IV_MODE", "IV_N_RESET", "IV_N_EMPTY", "IV_N_TASKS")
N_IVARS = IVARS.size

# Vector kernels' arrays. The batch is laid out in few arrays, because numba's dispatch and
# the hand-off to the threads cost per array argument (~1.4 us a call for the fifteen
# per-plant arrays these merge):
# * ``table`` (n, N_TABLE) float64, a row per plant: its parameters, state, excitation
#   (u0, nu), interval stats, next episode's parameter and starting vectors, and core
#   workspace, in the column ranges below (the kernels take views of them);
# * ``obs`` (2, n, N_OBS) float32: the current observations and, in same-step autoreset,
#   the final ones of episodes that ended (OB_NOW, OB_FINAL);
# * ``flags`` (N_FLAGS, n) bool and ``counters`` (N_COUNTERS, n) int64, a row per quantity.
TABLE = Layout("plant table")
T_P = TABLE.take("T_P", N_PARAMS)
T_S = TABLE.take("T_S", N_STATE)
T_CTRL = TABLE.take("T_CTRL", 2)
T_STATS = TABLE.take("T_STATS", N_STATS)
T_NEW_P = TABLE.take("T_NEW_P", N_PARAMS)
T_NEW_INIT = TABLE.take("T_NEW_INIT", N_INIT)
T_WORK = TABLE.take("T_WORK", N_WORK)
N_TABLE = TABLE.size
OB_NOW, OB_FINAL = range(2)
FLAGS = Layout("flags")
F_TERMINATED, F_TRUNCATED, F_AUTORESET, F_DID_RESET = FLAGS.group(
    "F_TERMINATED", "F_TRUNCATED", "F_AUTORESET", "F_DID_RESET")
N_FLAGS = FLAGS.size
COUNTERS = Layout("counters")
CT_STEPS, CT_CURSOR, CT_STATUS = COUNTERS.group("CT_STEPS", "CT_CURSOR", "CT_STATUS")
N_COUNTERS = COUNTERS.size

#: Every layout of the environments, for the overlap tests.
LAYOUTS = (CONFIG, RESULTS, INIT, DRAWS, OBS, IVARS, TABLE, FLAGS, COUNTERS)
