"""What a run returns and starts from: ``OscillatorState``, ``RunStats`` and ``Trajectory``.

:mod:`fricenv.simulate` makes them (and re-exports them); they hold arrays and numbers,
and know how to show themselves, but run nothing but the start's mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from . import core
from .checks import check_bounded_real, check_finite_real, got
from .layout import (
    EVENT_REVERSAL,
    EVENT_SLIP,
    EVENT_STICK,
    N_STATE,
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
)
from .params import PARAM_LIMIT, OscillatorParams

if TYPE_CHECKING:
    from matplotlib.axes import Axes

EVENT_NAMES = {EVENT_STICK: "stick", EVENT_SLIP: "slip", EVENT_REVERSAL: "reversal"}
EVENT_DTYPE = np.dtype([("t", "f8"), ("kind", "i1"), ("name", "U8"), ("x", "f8")])


def _check_params(params: OscillatorParams) -> None:
    if not isinstance(params, OscillatorParams):
        raise TypeError(f"params must be an OscillatorParams, got {type(params).__name__}")


@dataclass(frozen=True)
class OscillatorState:
    """Where a run is: time, displacement, velocity, mode and the two tone phases.

    ``mode`` is -1 (slip below belt speed), 0 (stick) or +1 (slip above). The phases are
    accumulated, so continuing a run after changing u0 or nu keeps the force continuous.
    """

    t: float = 0.0
    x: float = 0.0
    v: float = 0.0
    mode: int = -1
    phase1: float = 0.0
    phase2: float = 0.0

    @classmethod
    def start(cls, params: OscillatorParams, x0: float = 0.0, v0: float = 0.0, *,
              t0: float = 0.0, phase1: float = 0.0, phase2: float = 0.0) -> OscillatorState:
        """A consistent start: stick iff v0 == V and the static friction can hold the block."""
        _check_params(params)
        x0 = check_bounded_real("x0", x0, PARAM_LIMIT)
        v0 = check_bounded_real("v0", v0, PARAM_LIMIT)
        t0 = check_finite_real("t0", t0)
        phase1 = check_finite_real("phase1", phase1)
        phase2 = check_finite_real("phase2", phase2)
        mode = core.initial_mode(params.to_array(), x0, v0, phase1, phase2)
        return cls(t0, x0, v0, int(mode), phase1, phase2)

    def to_array(self) -> np.ndarray:
        s = np.empty(N_STATE)
        s[S_T], s[S_X], s[S_V], s[S_MODE] = self.t, self.x, self.v, self.mode
        s[S_PHI1], s[S_PHI2] = self.phase1, self.phase2
        return s

    @classmethod
    def from_array(cls, s: np.ndarray) -> OscillatorState:
        """The state in a kernels' state vector ``s`` (layout ``layout.S_*``); ``ValueError``
        naming ``s`` unless it is one, with a mode of -1, 0 or 1."""
        if not (isinstance(s, np.ndarray) and s.shape == (N_STATE,) and s.dtype.kind in "fiu"):
            what = (f"got shape {s.shape} and dtype {s.dtype}" if isinstance(s, np.ndarray)
                    else got(s))
            raise ValueError(f"s must be a state vector: a real array of shape ({N_STATE},) "
                             f"in the layout.S_* order, {what}")
        if s[S_MODE] not in (-1.0, 0.0, 1.0):
            raise ValueError(f"s[S_MODE] (the mode) must be -1, 0 or 1, got {float(s[S_MODE])!r}")
        return cls(float(s[S_T]), float(s[S_X]), float(s[S_V]), int(s[S_MODE]),
                   float(s[S_PHI1]), float(s[S_PHI2]))


@dataclass(frozen=True)
class RunStats:
    """What a stats-only run measured over its span."""

    duration: float
    stick_time: float
    n_stick: int
    n_slip: int
    n_reversals: int
    v_max: float
    v_min: float
    x_max: float
    x_min: float
    vr2_integral: float
    n_steps: int
    state: OscillatorState
    #: The parameters the run was differentiated by (``run_stats(wrt=...)``), and the
    #: derivatives by each, in that order: of ``vr2_integral``, ``stick_time`` and the
    #: final ``x`` and ``v`` (keys of those names); empty without ``wrt``.
    wrt: tuple[str, ...] = ()
    derivatives: dict[str, np.ndarray] = field(default_factory=dict, repr=False)

    @property
    def stick_fraction(self) -> float:
        return self.stick_time / self.duration if self.duration > 0 else 0.0

    @property
    def rms_relative_velocity(self) -> float:
        return math.sqrt(max(self.vr2_integral, 0.0) / self.duration) if self.duration > 0 else 0.0

    @classmethod
    def from_array(cls, st: np.ndarray, state: OscillatorState) -> RunStats:
        # The kernels sum stick phases step by step and the duration as one time, so a run
        # stuck throughout could read a stick time some ulps above its duration.
        return cls(
            duration=float(st[ST_DURATION]),
            stick_time=float(min(st[ST_STICK_TIME], st[ST_DURATION])),
            n_stick=int(st[ST_N_STICK]), n_slip=int(st[ST_N_SLIP]),
            n_reversals=int(st[ST_N_REVERSAL]), v_max=float(st[ST_V_MAX]),
            v_min=float(st[ST_V_MIN]), x_max=float(st[ST_X_MAX]), x_min=float(st[ST_X_MIN]),
            vr2_integral=float(st[ST_VR2_INT]), n_steps=int(st[ST_N_STEPS]), state=state,
        )


@dataclass(frozen=True)
class Trajectory:
    """A recorded run: the state on the output grid and every switching event.

    ``mode`` is -1/0/+1 (slip below belt, stick, slip above) at each output time;
    ``event_kind`` uses :data:`fricenv.layout.EVENT_STICK`, ``EVENT_SLIP`` and
    ``EVENT_REVERSAL`` (names in :data:`EVENT_NAMES`).
    """

    params: OscillatorParams
    method: str
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    mode: np.ndarray
    event_t: np.ndarray
    event_kind: np.ndarray
    event_x: np.ndarray
    stats: RunStats = field(repr=False)
    #: With ``simulate(wrt=...)``: the names differentiated by, and the derivatives of x
    #: and v at each output time (shape ``(n_out, len(wrt))``, columns in ``wrt``'s order)
    #: and of each switch's time (``(n_events, len(wrt))``). ``singular`` lists the points
    #: where the derivative does not exist (time, kind, name: a grazing contact, a
    #: tangential break-away, a stick/reversal tie); the derivatives are NaN from the first.
    wrt: tuple[str, ...] = ()
    dx_dp: np.ndarray | None = field(default=None, repr=False)
    dv_dp: np.ndarray | None = field(default=None, repr=False)
    event_t_dp: np.ndarray | None = field(default=None, repr=False)
    singular: np.ndarray | None = field(default=None, repr=False)

    @property
    def events(self) -> np.ndarray:
        """Every switch as a structured array with fields ``t``, ``kind`` (1 stick, 2 slip,
        3 reversal), ``name`` and ``x``, in time order."""
        out = np.empty(self.event_t.shape[0], dtype=EVENT_DTYPE)
        out["t"] = self.event_t
        out["kind"] = self.event_kind
        out["name"] = [EVENT_NAMES[int(k)] for k in self.event_kind]
        out["x"] = self.event_x
        return out

    @property
    def stick_fraction(self) -> float:
        """Share of the time spent stuck, from the exact stick durations (not the grid)."""
        return self.stats.stick_fraction

    @property
    def n_stick(self) -> int:
        """Number of stick phases entered (slip -> stick switches)."""
        return self.stats.n_stick

    @property
    def n_reversals(self) -> int:
        """Direct reversals through v = V without sticking."""
        return self.stats.n_reversals

    @property
    def n_steps(self) -> int:
        return self.stats.n_steps

    @property
    def final_state(self) -> OscillatorState:
        return self.stats.state

    def plot(self, ax: Axes | None = None, *, y: str = "v") -> Axes:
        """Draw ``v`` (default, with the belt speed and stick intervals shaded) or ``x``
        against time on ``ax`` and return it; without ``ax``, on a new pyplot figure, so
        that a notebook shows it, as ``pandas`` and ``xarray`` plots do."""
        if y not in ("v", "x"):
            raise ValueError(f"y must be 'v' or 'x', got {y!r}")
        from . import plotting

        if ax is None:
            import matplotlib.pyplot as plt

            ax = plt.figure(figsize=(8, 3.2), layout="constrained").add_subplot()
        if y == "v":
            plotting.draw_velocity(ax, self.t, self.v, self.mode, self.params.V)
        else:
            plotting.draw_displacement(ax, self.t, self.x)
        ax.set_title(plotting.params_title(self.params), fontsize=10)
        return ax

    def summary(self) -> dict:
        """Headline figures of the run, for printing."""
        s = self.stats
        return {
            "method": self.method, "t_end": float(self.t[-1]),
            "stick_fraction": s.stick_fraction, "n_stick": s.n_stick,
            "n_reversals": s.n_reversals, "v_min": s.v_min, "v_max": s.v_max,
            "x_min": s.x_min, "x_max": s.x_max,
        }
