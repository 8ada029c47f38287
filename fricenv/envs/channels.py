"""The observation's channels, declared once: names, order, layout and bounds.

Every environment observes the same nine channels. This module is the one declaration of
them: the kernels' slots (``tables.O_*``, laid out by :attr:`ObservationSpec.layout`),
the sensors' channel names (``obs_noise``, ``observe``), the observation box
(:meth:`ObservationSpec.box`) and the names a shipped run records all derive from
:data:`OBSERVATION`. It imports no kernel, so that the layouts (``fricenv.envs.tables``)
can build on it; the maps between plants and observations are
:mod:`fricenv.envs.observation`'s.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from fricenv.slots import Layout


@dataclass(frozen=True)
class Limits:
    """What an observation's bounds depend on: the scene's position and velocity limits
    and the ranges of the settings."""

    x_limit: float
    v_limit: float
    u0_range: tuple[float, float]
    nu_range: tuple[float, float]


@dataclass(frozen=True)
class Channel:
    """One channel: ``name`` (as the sensor options and shipped runs spell it), ``slot``
    (the kernels' layout name), ``bounds`` (its range under ``Limits``) and what it is."""

    name: str
    slot: str
    bounds: Callable[[Limits], tuple[float, float]]
    meaning: str


def _unit(_: Limits) -> tuple[float, float]:
    return -1.0, 1.0


@dataclass(frozen=True, eq=False)
class ObservationSpec:
    """An ordered set of named channels; the layout, names and bounds derive from it."""

    channels: tuple[Channel, ...]
    #: Names that stand for several channels in the ``observe`` option.
    groups: dict[str, tuple[str, ...]]

    def __post_init__(self) -> None:
        names = [c.name for c in self.channels]
        if len(set(names)) != len(names):
            raise ValueError(f"observation channels must have distinct names, got {names}")
        for group, members in self.groups.items():
            unknown = [m for m in members if m not in names]
            if unknown or group in names:
                raise ValueError(f"channel group {group!r} must name channels of {names} "
                                 f"and not be one, got {members}")

    @property
    def names(self) -> tuple[str, ...]:
        """The channels' names, in the observation's order."""
        return tuple(c.name for c in self.channels)

    @property
    def size(self) -> int:
        return len(self.channels)

    @property
    def layout(self) -> Layout:
        """The kernels' layout of the observation vector (one slot per channel)."""
        lay = Layout("observation")
        lay.group(*(c.slot for c in self.channels))
        return lay

    def index(self, name: str) -> int:
        """The position of channel ``name``; ``ValueError`` naming it and the channels."""
        try:
            return self.names.index(name)
        except ValueError:
            raise ValueError(f"unknown observation channel {name!r}; expected one of "
                             f"{self.names}") from None

    def box(self, limits: Limits) -> tuple[np.ndarray, np.ndarray]:
        """The observation box (low, high), float32, of an environment with ``limits``:
        where the exact observation is clipped and where noisy readings saturate."""
        lo, hi = zip(*(c.bounds(limits) for c in self.channels), strict=True)
        return np.array(lo, dtype=np.float32), np.array(hi, dtype=np.float32)

    def describe(self, channels: Sequence[int] | None = None) -> list[str]:
        """The names of the observed ``channels`` (indices; None: all), as a shipped run
        records them."""
        names = self.names
        return list(names) if channels is None else [names[i] for i in channels]


#: The environments' observation (``kernels.write_obs`` writes it, in this order).
OBSERVATION = ObservationSpec(
    channels=(
        Channel("x", "O_X", lambda lim: (-lim.x_limit, lim.x_limit),
                "displacement, clipped to the scene's x limit"),
        Channel("v_rel", "O_VR", lambda lim: (-lim.v_limit, lim.v_limit),
                "velocity relative to the belt, v - V, clipped to the v limit"),
        Channel("stick", "O_STICK", lambda lim: (0.0, 1.0), "1 when stuck, else 0"),
        Channel("cos1", "O_COS1", _unit, "cosine of the first tone's phase"),
        Channel("sin1", "O_SIN1", _unit, "sine of the first tone's phase"),
        Channel("cos2", "O_COS2", _unit, "cosine of the second tone's phase"),
        Channel("sin2", "O_SIN2", _unit, "sine of the second tone's phase"),
        Channel("u0", "O_U0", lambda lim: lim.u0_range, "the applied amplitude"),
        Channel("nu", "O_NU", lambda lim: lim.nu_range, "the applied frequency ratio"),
    ),
    groups={"phases": ("cos1", "sin1", "cos2", "sin2"), "settings": ("u0", "nu")},
)
#: The channels' names in order (the sensor options' and shipped runs' spelling).
CHANNELS = OBSERVATION.names
#: Names that stand for several channels in ``observe``.
CHANNEL_GROUPS = OBSERVATION.groups
