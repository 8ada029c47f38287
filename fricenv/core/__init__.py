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
loops): ``reset_stats``, ``initial_state``, the stats-only ``advance`` / ``advance_ws`` and
the recording ``record`` used by :mod:`fricenv.simulate`. Each method also has its own
entry kernels (``advance_exact``, ``record_event``, ...; :func:`kernels_for` picks them),
which compile that method's code alone and take the run's settings as one ``Solver``;
``partial_kernel`` builds the per-method kernels of the sweeps and environments from
bodies written once. Array layouts are in :mod:`fricenv.layout`,
:mod:`fricenv.params` and ``workspace``.

Modules: building blocks ``constants``, ``workspace``, ``trig``, ``state``, ``context``,
``closed_form``, ``slip``, ``taylor``, ``rosenbrock``, ``roots``, ``proofs``, ``contacts``,
``stick``, ``stats``, ``recording``, ``whole_interval``; runners ``exact``, ``event``,
``rk4``; entry kernels ``api``. This package exports the public kernels and what a
caller needs to run them (``__all__``); every other name, private kernels, slot constants
and tolerances included, is imported from the module that defines it.
"""

from .api import (
    ENTRY_KERNELS,
    EntryKernels,
    Solver,
    advance,
    advance_any_ws,
    advance_event,
    advance_event_ws,
    advance_exact,
    advance_exact_ws,
    advance_ws,
    always_conditioned,
    kernels_for,
    method_for,
    partial_kernel,
    partial_kernels,
    record,
    record_event,
    record_exact,
)
from .context import closed_form_conditioned, conditioned_rows, most_scan_steps
from .recording import Recording, stats_only
from .rk4 import run_rk4
from .state import initial_mode, initial_state, reset_stats, stick_force
from .taylor import taylor_order
from .workspace import fresh_workspace, new_workspace

__all__ = [
    "ENTRY_KERNELS",
    "EntryKernels",
    "Recording",
    "Solver",
    "advance",
    "advance_event",
    "advance_event_ws",
    "advance_exact",
    "advance_exact_ws",
    "advance_any_ws",
    "advance_ws",
    "always_conditioned",
    "closed_form_conditioned",
    "conditioned_rows",
    "fresh_workspace",
    "initial_mode",
    "initial_state",
    "kernels_for",
    "method_for",
    "most_scan_steps",
    "new_workspace",
    "partial_kernel",
    "partial_kernels",
    "record",
    "record_event",
    "record_exact",
    "reset_stats",
    "run_rk4",
    "stats_only",
    "stick_force",
    "taylor_order",
]
