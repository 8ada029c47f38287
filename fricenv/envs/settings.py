"""The settings every fricenv environment is made with, declared once.

``EnvSettings`` names what a plant, its control and its instruments are: the scene and the
changes made to it, the solver method, the sensor and actuator options. The single
environment (``StickSlipEnv``), the vector environment (``StickSlipVectorEnv``) and the
SB3 adapter (``StickSlipSB3VecEnv``) take one as ``settings=``, or its fields as keywords
(which is how ``gymnasium.make`` passes them); ``EnvSetup.build`` derives the scene, the
spaces and the kernels' configuration from it.

The fields are declared here and nowhere else. ``EnvKwargs`` is the same fields as a
``TypedDict``, so that type checkers and editors know the keywords of
``**kwargs: Unpack[EnvKwargs]`` (a test holds its names and types to the record's), and
:func:`settings_signature` gives the constructors a runtime signature that lists every
field as a keyword with its default, for ``help()``, IPython and notebooks.

The record keeps the values as given; they are checked where they are used
(``EnvSetup.build``, so by every environment's constructor), and an error names the field
and the value.
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any, TypedDict, TypeVar

if TYPE_CHECKING:
    from fricenv.envs.scenes import Scene


@dataclass(frozen=True)
class EnvSettings:
    """What an environment's plants are and how they are controlled and observed.

    ``EnvSettings(scene="self_excited", obs_noise=0.05)`` is what
    ``StickSlipEnv(scene="self_excited", obs_noise=0.05)`` makes; pass it as
    ``settings=`` to ``StickSlipEnv``, ``StickSlipVectorEnv`` or ``StickSlipSB3VecEnv``,
    or its fields to ``gymnasium.make`` as keywords (``**settings.as_kwargs()``).
    ``replace(**changes)`` gives a copy with some fields changed.

    The fields (every one optional; the defaults leave the scene as it is):

    - `scene`: `"paper"`, `"self_excited"`, `"stribeck"`, `"viscous"` or a `Scene`: plant,
      ranges, reward weights, start and horizon.
    - `action_mode`: `"amplitude"`, `"frequency"` or `"both"` (None: the scene's).
    - `incremental`: actions change the settings instead of setting them (a bool).
    - `control_dt`: control interval in time units (None: the scene's, pi/6 in the
      presets; at least 1e-6).
    - `randomize`: draw the plant parameters per episode from the scene's ranges (a bool).
    - `reward_weights`: `(w_stick, w_velocity, w_effort)` or a dict with some of those keys
      (None: the scene's).
    - `params`: overrides of the scene's nominal plant, e.g. `{"lam": 0.2}`; with
      `randomize`, a parameter given here keeps its value in every episode.
    - `method`: `"auto"` (closed form for Coulomb, event integrator otherwise), `"exact"`
      or `"event"`.
    - `obs_noise`: Gaussian noise on the observation: one standard deviation, nine, or a
      dict `{channel: std}` (None: none).
    - `obs_delay`: the observation is the reading of this many control intervals earlier.
    - `observe`: the observed channels, e.g. `("x", "phases")` (None: all nine).
    - `actuator_lag`: time constant of the first-order lag of the applied setting behind
      the commanded one (0: none).
    - `actuator_rate`: largest change of the applied setting per control interval, as a
      fraction of each range (None: no limit).
    - `randomize_sensors`: each episode draws its noise scale (uniform in [0, 1), times
      `obs_noise`) and its delay (uniform in `0 .. obs_delay`) (a bool).

    `StickSlipEnv`'s docstring says more of each.
    """

    scene: str | Scene = "paper"
    action_mode: str | None = None
    incremental: bool = False
    control_dt: float | None = None
    randomize: bool = False
    reward_weights: Sequence[float] | Mapping[str, float] | None = None
    params: Mapping[str, float] | None = None
    method: str = "auto"
    obs_noise: float | Sequence[float] | Mapping[str, float] | None = None
    obs_delay: int = 0
    observe: str | Sequence[str] | None = None
    actuator_lag: float = 0.0
    actuator_rate: float | None = None
    randomize_sensors: bool = False

    @classmethod
    def of(cls, settings: EnvSettings | None, kwargs: Mapping[str, Any],
           where: str) -> EnvSettings:
        """The settings an environment's constructor was given: ``settings``, or a record of
        the keywords ``kwargs`` (``TypeError`` naming ``where`` and the keyword for one that
        is not a field, or when both are given)."""
        if settings is None:
            return cls.from_kwargs(kwargs, where)
        if not isinstance(settings, EnvSettings):
            raise TypeError(f"{where}: settings must be an EnvSettings or None, got "
                            f"{type(settings).__name__} {settings!r}")
        if kwargs:
            raise TypeError(
                f"{where}: give the settings either as settings= or as keywords, not both "
                f"(got settings= and {', '.join(f'{k}=' for k in kwargs)}); for "
                "gymnasium.make, which passes the id's scene= itself, pass "
                "**settings.as_kwargs(), and settings.replace(...) changes some fields")
        return settings

    @classmethod
    def from_kwargs(cls, kwargs: Mapping[str, Any], where: str) -> EnvSettings:
        """A record of the keywords ``kwargs`` (``TypeError`` naming ``where`` and every
        keyword that is not a field, with the fields there are)."""
        cls._check_names(kwargs, where)
        return cls(**kwargs)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The fields' names, in order."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def _check_names(cls, kwargs: Mapping[str, Any], where: str) -> None:
        names = cls.names()
        unknown = [k for k in kwargs if k not in names]
        if unknown:
            raise TypeError(f"{where} got unknown keyword argument(s) {unknown}; the "
                            f"settings are {list(names)}")

    def as_kwargs(self) -> dict[str, Any]:
        """The fields as keywords (values as held, not copied), e.g. for ``gymnasium.make``."""
        return {name: getattr(self, name) for name in self.names()}

    def replace(self, **changes: Any) -> EnvSettings:
        """A copy with ``changes`` (``TypeError`` naming any keyword that is not a field)."""
        self._check_names(changes, "EnvSettings.replace")
        return dataclasses.replace(self, **changes)


class EnvKwargs(TypedDict, total=False):
    """``EnvSettings``' fields as keywords, for ``**kwargs: Unpack[EnvKwargs]`` (the names
    and types are the record's: a test compares them)."""

    scene: str | Scene
    action_mode: str | None
    incremental: bool
    control_dt: float | None
    randomize: bool
    reward_weights: Sequence[float] | Mapping[str, float] | None
    params: Mapping[str, float] | None
    method: str
    obs_noise: float | Sequence[float] | Mapping[str, float] | None
    obs_delay: int
    observe: str | Sequence[str] | None
    actuator_lag: float
    actuator_rate: float | None
    randomize_sensors: bool


_Init = TypeVar("_Init", bound=Callable[..., None])


def settings_signature(init: _Init) -> _Init:
    """Give a constructor declared ``(..., **kwargs: Unpack[EnvKwargs])`` the runtime
    signature with each of ``EnvSettings``' fields as a keyword-only argument with its
    default, in place of ``**kwargs`` (what ``help()``, IPython and notebooks show); type
    checkers keep seeing the declared signature."""
    sig = inspect.signature(init)
    params = [p for p in sig.parameters.values() if p.kind is not p.VAR_KEYWORD]
    params += [inspect.Parameter(f.name, inspect.Parameter.KEYWORD_ONLY, default=f.default,
                                 annotation=f.type) for f in fields(EnvSettings)]
    init.__signature__ = sig.replace(parameters=params)  # type: ignore[attr-defined]
    return init
