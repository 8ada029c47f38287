"""What a friction law declares: its parameters, its force, and what the solvers may assume.

A law is a :class:`FrictionLaw` record built once in the law's own module
(:mod:`fricenv.friction.coulomb`, ...). Everything outside the law's module reads the law
through this record (Python side) or through :mod:`fricenv.friction.kernels` (inside the
numba kernels); nothing else tests a law's coefficients.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: Force of a law in slip, vectorised: ``force(vr, values, xfk, xfs)`` with ``vr != 0`` the
#: slip velocity v - V and ``values`` the law's parameters by name; returns F(vr), the
#: friction force acting against the slip (the equation of motion has ``- F``).
#: Length of the longest Taylor series the event method carries (its highest order + 1);
#: a law's scratch series (``SCRATCH`` in its module) are this long.
SERIES_LEN = 21

ForceFn = Callable[[np.ndarray, Mapping[str, float], float, float], np.ndarray]


@dataclass(frozen=True)
class LawParam:
    """One parameter of a friction law: its name, default, valid range and meaning.

    ``low``/``high`` bound the value (``low_open``: ``low`` itself is excluded);
    ``integer``: only whole numbers are valid.
    """

    name: str
    default: float
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    integer: bool = False
    doc: str = ""

    def check(self, value: float, law: str) -> None:
        """``ValueError`` naming the parameter, its value and its range if out of it."""
        lo_ok = value > self.low if self.low_open else value >= self.low
        if not (lo_ok and value <= self.high):
            op = ">" if self.low_open else ">="
            rng = f"{op} {self.low:g}" + (f" and <= {self.high:g}" if self.high < math.inf
                                           else "")
            raise ValueError(f"{self.name} of the {law} law must be {rng}, got {value!r}")
        if self.integer and value != math.floor(value):
            raise ValueError(
                f"{self.name} of the {law} law must be a whole number, got {value!r}: "
                f"|v - V|**{self.name} is analytic at break-away (v = V) only for whole "
                "exponents, and the event method's Taylor steps need an analytic force")


@dataclass(frozen=True)
class FrictionLaw:
    """A friction law: ``F(vr)`` in slip, sticking while ``|f| <= xfs``.

    | field | meaning |
    |---|---|
    | name | the law's name (its module's) |
    | code | its number inside the kernels (``fricenv.friction.kernels``) |
    | params | its own parameters, beside the levels ``xfk`` and ``xfs`` that all laws share |
    | closed_form | the slip equation is linear, so the ``exact`` method's closed form applies |
    | continuous | F is continuous at break-away (F(0+) = xfs), not a jump to ``xfk`` |
    | force | ``F(vr)`` for ``vr != 0``, vectorised (:data:`ForceFn`) |
    | near_belt_slope | ``-dF/dvr`` as ``vr -> 0+``: the damping slip near V loses |
    | envelope | ``(level, b1, b3)``: a cubic law that bounds this one (divergence bound) |
    | stiffness | the largest abs(dv'/dv) of slip not growing with the speed, vectorised |
    | runs_away | ``(values, lam)``: slip has negative net damping, so the motion grows |
    """

    name: str
    code: int
    params: tuple[LawParam, ...]
    closed_form: bool
    continuous: bool
    summary: str
    force: ForceFn
    near_belt_slope: Callable[[Mapping[str, float], float, float], float]
    envelope: Callable[[Mapping[str, float], float, float], tuple[float, float, float]]
    stiffness: Callable[[Mapping[str, Any], Any, Any, Any], Any]
    runs_away: Callable[[Mapping[str, float], float], bool]
    presets: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def defaults(self) -> dict[str, float]:
        return {p.name: p.default for p in self.params}

    def check(self, values: Mapping[str, float]) -> None:
        """``ValueError`` naming the first parameter out of its range."""
        for p in self.params:
            p.check(values[p.name], self.name)
