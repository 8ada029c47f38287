"""fricenv: exact event-driven simulation of a two-tone forced dry-friction oscillator."""

from .params import FRICTION_LAWS, OscillatorParams
from .simulate import (
    EVENT_NAMES,
    OscillatorState,
    RunStats,
    SimulationError,
    Trajectory,
    run_stats,
    simulate,
)

__all__ = [
    "EVENT_NAMES",
    "FRICTION_LAWS",
    "OscillatorParams",
    "OscillatorState",
    "RunStats",
    "SimulationError",
    "Trajectory",
    "run_stats",
    "simulate",
]
__version__ = "0.1.0"

from .envs import register_envs as _register_envs  # noqa: E402

_register_envs()  # gymnasium.make("fricenv/StickSlip-v0") works after `import fricenv`
