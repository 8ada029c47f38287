"""fricenv: exact event-driven simulation of a two-tone forced dry-friction oscillator."""

# First, before any module with compiled kernels: keys their numba cache on the whole
# package's source (see _numba_cache).
from . import _numba_cache  # noqa: F401
from .mapfile import MapInUseError
from .params import FRICTION_LAWS, OscillatorParams
from .regimes import Regime, classify, classify_stats, strobe_period
from .simulate import (
    EVENT_NAMES,
    OscillatorState,
    RunStats,
    SimulationError,
    Trajectory,
    run_stats,
    simulate,
)
from .sweep import RegimeMap, SweepSettings, cell_statistics, regime_map

__all__ = [
    "EVENT_NAMES",
    "FRICTION_LAWS",
    "MapInUseError",
    "OscillatorParams",
    "OscillatorState",
    "Regime",
    "RegimeMap",
    "RunStats",
    "SimulationError",
    "SweepSettings",
    "Trajectory",
    "cell_statistics",
    "classify",
    "classify_stats",
    "regime_map",
    "run_stats",
    "simulate",
    "strobe_period",
]
__version__ = "0.1.0"

from .envs import register_envs as _register_envs  # noqa: E402

_register_envs()  # gymnasium.make("fricenv/StickSlip-v0") works after `import fricenv`
