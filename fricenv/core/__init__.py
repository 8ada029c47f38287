"""Numba kernels of the stick-slip oscillator (paper's Eq. 7), one module per concern.

Three integrators share one event logic:

* ``exact`` (Coulomb law, b1 = b3 = 0): each slip step is the closed-form solution of the
  linear slip equation (homogeneous transition matrix for any damping, including the
  critically damped and resonant cases, plus the particular response to each tone); each
  stick phase is exact. Only switching instants are found numerically, by bracketed
  Halley iteration on the closed form. A stats-only call that reads no extrema (an
  environment's control interval) is first tried as one closed-form step, taken when a
  bound on each part of the motion proves it switch-free; its (v - V)^2 integral is then
  exact too.
* ``event`` (any friction law): Taylor-series steps inside slip phases (the slip equation
  is polynomial, so the series' coefficients follow from a recurrence; order about
  -ln(rtol) / 2, step length from the decay of the last terms, Jorba & Zou 2005), exact
  stick phases. The series is the step's dense output: switches, extrema and output
  times are found on it, and the (v - V)^2 integral is exact on it. Stiff stretches of a
  stats-only run take L-stable Rosenbrock 4(3) steps where no dense output is needed.
* ``rk4``: the paper's fixed-step RK4 with ``sgn``, kept as the baseline. It cannot
  represent sticking.

Switches (slip -> stick, stick -> slip, reversal) are searched on every step: a sign
change at the ends, and an interior extremum located from the sign change of the
derivative. A step is halved until it provably holds at most one extremum (curvature
bounds: ``_one_extremum_at_most``, ``_v_one_extremum``, ``_sign_kept``); that is how
grazing contacts, where ``v`` touches ``V`` tangentially, are caught.

Public kernels (all compiled by :func:`fricenv.jit.kernel`, allocation-free in their step
loops):
``reset_stats``, ``initial_state``, ``advance`` (stats only) and the recording runners used
by :mod:`fricenv.simulate`. Array layouts are in :mod:`fricenv.layout` and
:mod:`fricenv.params`.

Modules: building blocks ``constants``, ``workspace``, ``trig``, ``state``, ``context``,
``closed_form``, ``slip``, ``taylor``, ``rosenbrock``, ``roots``, ``proofs``, ``contacts``,
``stick``, ``stats``, ``recording``, ``whole_interval``; runners ``exact``, ``event``,
``rk4``; entry kernels ``api``. This package re-exports their names.
"""

from ..layout import (  # noqa: F401
    EVENT_REVERSAL,
    EVENT_SLIP,
    EVENT_STICK,
    METHOD_EXACT,
    S_MODE,
    S_PHI1,
    S_PHI2,
    S_T,
    S_V,
    S_X,
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_SLIP,
    ST_N_STEPS,
    ST_N_STICK,
    ST_STICK_TIME,
    ST_V_MAX,
    ST_V_MIN,
    ST_VR2_INT,
    ST_X_MAX,
    ST_X_MIN,
    STATUS_BUFFER_FULL,
    STATUS_EVENT_CAP,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_TOO_STIFF,
)
from ..params import (  # noqa: F401
    P_B1,
    P_B3,
    P_LAM,
    P_U1,
    P_U2,
    P_V,
    P_W1,
    P_W2,
    P_XFK,
    P_XFS,
)
from .api import (  # noqa: F401
    advance,
    advance_ws,
    record,
)
from .closed_form import (  # noqa: F401
    _forcing,
    _homog,
    _jerk,
    _particular,
    _rotate,
    _rotate_by,
    _slip_and_phases_at,
    _slip_at,
    _slip_mid_and_end,
    _slip_start,
    _slip_with,
    _stick_at,
)
from .constants import (  # noqa: F401
    _D2_MIN,
    _STATUS_NEAR_RESONANCE,
    CLOSED_FORM_MAX_GAIN,
    DELTA_MAX,
    DELTA_WIDE,
    EVENT_REL_TOL,
    EXTREMUM_REL_TOL,
    GRAZE_REL,
    GRAZE_ULPS,
    I_MARGIN,
    I_P2_MIN,
    MAX_ROOT_ITER,
    MIN_SPLIT,
    PHASE_PER_STEP,
    PHASE_PER_STEP_WIDE,
    ROS_BACKOFF_MAX,
    STIFF_HK,
    TWO_PI,
)
from .contacts import (  # noqa: F401
    _RESOLVED,
    _contact_outcome,
    _contact_time,
    _force_tie,
    _start_slope,
    _stick_outcome,
    _unresolved_return,
)
from .context import (  # noqa: F401
    _scan_cap,
    _setup_context,
    _tone_d2,
    closed_form_conditioned,
    most_scan_steps,
)
from .event import (  # noqa: F401
    _run_event,
)
from .exact import (  # noqa: F401
    _run_exact,
    _scan_exact,
)
from .proofs import (  # noqa: F401
    _extremum_matters,
    _monotone,
    _one_extremum_at_most,
    _sign_kept,
    _stays_positive,
    _stick_held,
    _v_one_extremum,
)
from .recording import (  # noqa: F401
    _log_event,
    _record_event,
)
from .rk4 import (  # noqa: F401
    _sgn_acc,
    run_rk4,
)
from .roots import (  # noqa: F401
    K_DENSE_H,
    K_DENSE_V,
    K_SLIP_H,
    K_SLIP_V,
    K_STICK_F,
    _bracket,
    _extremum,
    _feval,
    _hermite_root,
    _root,
)
from .rosenbrock import (  # noqa: F401
    _RA21,
    _RA31,
    _RA32,
    _RALPHA3,
    _RB1,
    _RB2,
    _RB3,
    _RB4,
    _RC21,
    _RC31,
    _RC32,
    _RC41,
    _RC42,
    _RC43,
    _RE1,
    _RE2,
    _RE4,
    _RG,
    _RG1,
    _RG2,
    _RG3,
    _RG4,
    _ros4_step,
    _ros_solve,
)
from .slip import (  # noqa: F401
    _acc,
    _carry,
    _end_phases,
    _rhs_acc,
    _set_phases,
    _step_inputs,
)
from .state import (  # noqa: F401
    _end_call,
    _note_v,
    _note_x,
    initial_mode,
    initial_state,
    reset_stats,
    stick_force,
)
from .stats import (  # noqa: F401
    _slip_extrema,
    _slip_stats,
    _vr2_from_values,
    _x_extrema_between,
)
from .stick import (  # noqa: F401
    _stick_exit_time,
)
from .taylor import (  # noqa: F401
    _SUMS,
    _dense_bounds,
    _dense_v,
    _dense_x,
    _taylor_coeffs,
    _taylor_vr2,
    taylor_order,
)
from .trig import (  # noqa: F401
    _C2,
    _C4,
    _C6,
    _C8,
    _C10,
    _C12,
    _C14,
    _C16,
    _C18,
    _INV,
    _S3,
    _S5,
    _S7,
    _S9,
    _S11,
    _S13,
    _S15,
    _S17,
    _S19,
    _renorm,
    _sincos,
    _sincos_long,
    _wrap,
)
from .whole_interval import (  # noqa: F401
    _arc_passes_zero,
    _cget,
    _cset,
    _e1,
    _interval_constants,
    _interval_e,
    _lowest,
    _tone_dir,
    _whole_interval,
)
from .workspace import (  # noqa: F401
    C_B1,
    C_B3,
    C_C1A,
    C_C2A,
    C_CE1,
    C_CE2,
    C_CP1,
    C_CP2,
    C_DV,
    C_DX,
    C_GDD,
    C_GDDD,
    C_KC1,
    C_KC2,
    C_KS1,
    C_KS2,
    C_LAM,
    C_P2,
    C_RES1,
    C_RES2,
    C_S1A,
    C_S2A,
    C_SD,
    C_SE1,
    C_SE2,
    C_SP1,
    C_SP2,
    C_TN,
    C_TQ,
    C_TV,
    C_TW,
    C_TX,
    C_U1,
    C_U2,
    C_V,
    C_VA,
    C_VDD_H,
    C_VDD_P,
    C_VDDD_H,
    C_VDDD_P,
    C_W1,
    C_W2,
    C_XA,
    C_XFK,
    C_XFS,
    N_CX,
    N_I_TONE,
    N_T,
    N_WORK,
    T_NEAR_RES,
    TAYLOR_MAX_ORDER,
    W_C1,
    W_C2,
    W_I_AMP1,
    W_I_AMP2,
    W_I_E12,
    W_I_EH,
    W_I_EHC,
    W_I_EHH,
    W_I_F11,
    W_I_KEY_E1,
    W_I_KEY_E2,
    W_I_KEY_LAM,
    W_I_KEY_T,
    W_I_KEY_W1,
    W_I_KEY_W2,
    W_I_P,
    W_I_TONE1,
    W_KEY_H,
    W_KEY_LAM,
    W_KEY_W1,
    W_KEY_W2,
    W_M11,
    W_M12,
    W_M21,
    W_M22,
    W_MC1,
    W_MC2,
    W_MS1,
    W_MS2,
    W_PH1,
    W_PH2,
    W_R11,
    W_R12,
    W_R21,
    W_R22,
    W_RC1,
    W_RC2,
    W_RS1,
    W_RS2,
    W_S1,
    W_S2,
    W_SKIP_EXTREMA,
    W_SKIP_VR2,
    W_T_KEY,
    fresh_workspace,
    new_workspace,
)
