"""Friction laws: one module a law, and the registry that names them.

Each law's module (:mod:`~fricenv.friction.coulomb`, :mod:`~fricenv.friction.cubic`,
:mod:`~fricenv.friction.exponential`) declares a :class:`FrictionLaw` record (parameters
with bounds and defaults, the force, whether the closed form applies, whether friction is
continuous at break-away) and its numba functions; :mod:`fricenv.friction.kernels`
dispatches the solvers' questions to them. :func:`method_for` is the one place that
decides which method runs a law.

Adding a law: write its module, list it in :data:`LAWS` below and add its branch to each
function of :mod:`fricenv.friction.kernels`.
"""

from __future__ import annotations

import numpy as np

from . import coulomb, cubic, exponential
from .spec import FrictionLaw, LawParam

#: Every law by name, in the order of their codes.
LAWS: dict[str, FrictionLaw] = {law.name: law for law in (coulomb.LAW, cubic.LAW,
                                                             exponential.LAW)}
_BY_CODE = {law.code: law for law in LAWS.values()}

#: Named laws (the paper's three of Fig. 2, and the exponential Stribeck law): name ->
#: (law, its parameters).
PRESETS: dict[str, tuple[str, dict[str, float]]] = {
    name: (law.name, dict(values)) for law in LAWS.values()
    for name, values in law.presets.items()}
#: Every parameter some law owns -> that law.
OWNER: dict[str, str] = {p.name: law.name for law in LAWS.values() for p in law.params}


def law_named(name: str) -> FrictionLaw:
    """The law called ``name``; ``ValueError`` naming it and the valid names if unknown."""
    try:
        return LAWS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown friction law {name!r}; expected one of "
                         f"{sorted(LAWS)}") from None


def law_of_code(code: float) -> FrictionLaw:
    """The law whose kernel code is ``code``."""
    return _BY_CODE[int(code)]


def polynomial_law(b1: float, b3: float) -> FrictionLaw:
    """The law of a plant given by b1 and b3 alone (the paper's family): Coulomb where both
    are 0, else cubic (``cubic.family_code`` decides, here and inside the kernels)."""
    return law_of_code(cubic.family_code(b1, b3, float(coulomb.CODE)))


def polynomial_laws_in(b1_range: tuple[float, float], b3_range: tuple[float, float]
                       ) -> frozenset[str]:
    """The laws of the paper's family that plants drawn with b1 and b3 in these closed
    ranges ``(lo, hi)`` can have: ``coulomb`` where both ranges hold 0, ``cubic`` unless
    both are ``(0, 0)``."""
    (l1, h1), (l3, h3) = b1_range, b3_range
    # the plant nearest Coulomb each range holds, and whether both ends are that plant
    nearest = polynomial_law(min(max(0.0, l1), h1), min(max(0.0, l3), h3))
    return frozenset({nearest.name, polynomial_law(l1, l3).name, polynomial_law(h1, h3).name})


def method_for(law: FrictionLaw) -> str:
    """The method ``"auto"`` runs a law with: the closed form where the law's slip equation
    is linear, the event method otherwise."""
    return "exact" if law.closed_form else "event"


def closed_form_rows(codes: np.ndarray) -> np.ndarray:
    """Which law codes (an array) the closed form runs."""
    ok = [law.code for law in LAWS.values() if law.closed_form]
    return np.isin(np.asarray(codes), ok)


__all__ = ["LAWS", "OWNER", "PRESETS", "FrictionLaw", "LawParam", "closed_form_rows",
           "law_named", "law_of_code", "method_for", "polynomial_law", "polynomial_laws_in"]
