"""fricenv: exact event-driven simulation of a two-tone forced dry-friction oscillator.

``import fricenv`` loads no numba: the public names below are resolved on first use
(PEP 562), so that the command line's help, Gymnasium's registry and a process that only
reads a map file start in a fraction of a second. The first use of a name that needs the
kernels imports numba through :mod:`fricenv.jit`. The Gymnasium ids are registered on
import (:func:`fricenv.envs.register_envs`), which loads Gymnasium but not the
environments' classes.
"""

from __future__ import annotations

import copyreg as _copyreg
import importlib
import logging as _logging
import sys
import types
from typing import TYPE_CHECKING, Any

from ._tbb import preload as _preload_tbb
from ._version import __version__ as __version__

if TYPE_CHECKING:
    from . import atlas as atlas
    from .atlas.store import open_atlas as open_atlas
    from .calls import SweepInterrupted
    from .identification.design import Design, design_excitation
    from .identification.identify import IdentificationResult
    from .identification.identify import identify as identify
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

__all__ = [
    "Design",
    "EVENT_NAMES",
    "FRICTION_LAWS",
    "IdentificationResult",
    "MAX_STEPS_PER_CALL",
    "MAX_STEPS_PER_TAU",
    "MapInUseError",
    "OscillatorParams",
    "OscillatorState",
    "PeriodicOrbit",
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
    "design_excitation",
    "forcing_period",
    "identify",
    "lyapunov_exponent",
    "periodic_orbit",
    "regime_map",
    "run_stats",
    "simulate",
    "strobe_period",
    "threading_info",
    "warmup",
]

#: Where each public name lives (module relative to the package), imported on first use.
_HOMES: dict[str, str] = {
    "SweepInterrupted": "calls",
    "threading_info": "jit",
    "MapInUseError": "mapfile",
    "FRICTION_LAWS": "params",
    "OscillatorParams": "params",
    **dict.fromkeys(("Regime", "classify", "classify_stats", "strobe_period"), "regimes"),
    **dict.fromkeys(("EVENT_NAMES", "MAX_STEPS_PER_CALL", "MAX_STEPS_PER_TAU",
                     "OscillatorState", "RunStats", "SimulationError", "Trajectory",
                     "run_stats", "simulate"), "simulate"),
    **dict.fromkeys(("RegimeMap", "SweepSettings", "cell_statistics", "regime_map"),
                    "sweep"),
    **dict.fromkeys(("PeriodicOrbit", "forcing_period", "lyapunov_exponent",
                     "periodic_orbit"), "stability"),
    "warmup": "warmup",
    "open_atlas": "atlas.store",
    **dict.fromkeys(("Design", "IdentificationResult", "design_excitation", "identify"),
                    "identification"),
}
#: Public functions named like the module that defines them: importing that module
#: (``import fricenv.simulate``) must not rebind ``fricenv.simulate`` to the module.
_SHADOWED = ("simulate", "warmup")


def __getattr__(name: str) -> Any:
    """Import a public name's module on first use (``fricenv.atlas`` is the callable
    package, which needs Dask, Zarr and xarray: the ``scale`` extra)."""
    if name == "atlas":
        return importlib.import_module(".atlas", __name__)
    if name not in _HOMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__) | {"atlas", "open_atlas"})


class _Package(types.ModuleType):
    """The package module: keeps ``fricenv.simulate`` and ``fricenv.warmup`` the functions
    when the import system binds their modules as attributes of the package."""

    def __setattr__(self, name: str, value: Any) -> None:
        if name in _SHADOWED and isinstance(value, types.ModuleType):
            value = getattr(value, name)
        super().__setattr__(name, value)


def _import_package(name: str) -> Any:
    return importlib.import_module(name)


def _reduce_package(module: types.ModuleType) -> tuple[Any, tuple[str]]:
    return _import_package, (module.__name__,)


sys.modules[__name__].__class__ = _Package
# pickle (and cloudpickle, as Dask sends a function that names the package) reduces a
# plain module by its name; the subclass needs saying so
_copyreg.pickle(_Package, _reduce_package)

# Intel TBB where numba will look for it, before any parallel kernel chooses the threading
# layer (fricenv._tbb): the user's own kernels get the thread-safe layer too
_preload_tbb()

# The package logs through the "fricenv" logger and adds only a NullHandler. The compile
# notice goes to that logger where the application configured logging, else to stderr
# (fricenv.compile_notice); importing it hooks it to numba's compile event, which
# fricenv.jit listens to (it imports neither numba nor a kernel).
_logging.getLogger(__name__).addHandler(_logging.NullHandler())
from . import compile_notice as _compile_notice  # noqa: E402, F401
from .envs import register_envs as _register_envs  # noqa: E402

_register_envs()  # gymnasium.make("fricenv/StickSlip-v0") works after `import fricenv`
