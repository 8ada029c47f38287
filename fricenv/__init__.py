"""fricenv: exact event-driven simulation of a two-tone forced dry-friction oscillator."""

import logging as _logging

# First, before any module with compiled kernels: keys their numba cache on the whole
# package's source (see _numba_cache).
from . import _numba_cache  # noqa: F401
from .calls import SweepInterrupted
from .jit import threading_info
from .mapfile import MapInUseError
from .params import FRICTION_LAWS, OscillatorParams
from .regimes import Regime, classify, classify_stats, strobe_period
from .simulate import (
    EVENT_NAMES,
    MAX_STEPS_PER_CALL,
    MAX_STEPS_PER_TAU,
    OscillatorState,
    RunStats,
    SimulationError,
    Trajectory,
    run_stats,
    simulate,
)
from .sweep import RegimeMap, SweepSettings, cell_statistics, regime_map
from .warmup import warmup

# The package logs (the compile notice of fricenv.compile_notice) through the "fricenv"
# logger; as a library it adds only a NullHandler: the application decides what is shown.
_logging.getLogger(__name__).addHandler(_logging.NullHandler())

__all__ = [
    "EVENT_NAMES",
    "FRICTION_LAWS",
    "MAX_STEPS_PER_CALL",
    "MAX_STEPS_PER_TAU",
    "MapInUseError",
    "OscillatorParams",
    "OscillatorState",
    "Regime",
    "RegimeMap",
    "RunStats",
    "SimulationError",
    "SweepInterrupted",
    "SweepSettings",
    "Trajectory",
    "cell_statistics",
    "classify",
    "classify_stats",
    "regime_map",
    "run_stats",
    "simulate",
    "strobe_period",
    "threading_info",
    "warmup",
]
__version__ = "0.1.0"


def __getattr__(name: str) -> object:
    """``fricenv.atlas`` and ``fricenv.open_atlas`` on first use: they need Dask, Zarr
    and xarray (the ``scale`` extra), which ``import fricenv`` must not load."""
    if name in ("atlas", "open_atlas"):
        import importlib

        module = importlib.import_module(".atlas", __name__)  # callable: fricenv.atlas(...)
        return module if name == "atlas" else module.open_atlas
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


from .envs import register_envs as _register_envs  # noqa: E402

_register_envs()  # gymnasium.make("fricenv/StickSlip-v0") works after `import fricenv`
