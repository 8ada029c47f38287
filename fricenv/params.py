"""Model parameters of the two-tone forced mass-on-belt oscillator (paper's Eq. 7)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np

from .checks import check_bounded_real, got

# Layout of the float64 parameter vector that every kernel takes. Frequencies are stored,
# not (eta, nu), so that a controller may retune a tone without touching the other.
P_LAM, P_V, P_XFK, P_XFS, P_B1, P_B3, P_U1, P_U2, P_W1, P_W2 = range(10)
N_PARAMS = 10

#: Largest magnitude a parameter may have. The model is dimensionless and its quantities
#: are O(1) in the paper; far beyond that the kernels' squares and cubes of forces
#: overflow (u0 = 1e156 gave a state 2 % off and a NaN (v - V)^2 integral, with no error),
#: and a switching instant, found to rounding of tau (~1e-16), no longer resolves a slip
#: phase as short as 1 / xfk (xfk = 1e20 gave (v - V)^2 integrals 1e13 times too large).
PARAM_LIMIT = 1e12

#: Friction laws of the paper's Fig. 2, as (b1, b3).
FRICTION_LAWS: dict[str, tuple[float, float]] = {
    "coulomb": (0.0, 0.0),
    "viscous": (0.2, 0.0),
    "stribeck": (0.2, 0.16),
}
#: The paper's time-history cases (Figs. 4-7, Sec. 3.2.1): figure -> the fields
#: that differ from the defaults (Coulomb law, lam = 1/2, eta = 3/5, V = 1). One table for
#: the scripts, the reproduction and the tests.
PAPER_CASES: dict[str, dict[str, float]] = {
    "4a": {"nu": 0.10, "u0": 0.2},
    "4b": {"nu": 0.95, "u0": 0.05},
    "5a": {"nu": 0.10, "u0": 1.15},
    "5b": {"nu": 0.2, "u0": 3.05},
    "6": {"nu": 1.15, "u0": 0.7},
    "7": {"nu": 1.0, "u0": 1.65, "eta": 0.2},
}

_LAW_ALIASES = {
    "coulomb+viscosity": "viscous",
    "coulomb_viscosity": "viscous",
    "viscosity": "viscous",
    "complete": "stribeck",
}


def resolve_law(name: str) -> str:
    """Canonical name of a friction law; ``ValueError`` naming the input if unknown."""
    key = str(name).strip().lower()
    key = _LAW_ALIASES.get(key, key)
    if key not in FRICTION_LAWS:
        raise ValueError(
            f"unknown friction law {name!r}; expected one of {sorted(FRICTION_LAWS)}"
        )
    return key


def check_known_fields(cls_or_obj: Any, names: Iterable[str], what: str) -> None:
    """``ValueError`` listing the names that are not fields of a dataclass, and the valid ones."""
    known = {f.name for f in fields(cls_or_obj)}
    unknown = sorted(set(names) - known)
    if unknown:
        raise ValueError(f"unknown {what}(s) {unknown}; expected some of {sorted(known)}")


@dataclass(frozen=True)
class OscillatorParams:
    """Dimensionless parameters of the paper's Eq. 7.

    ``x'' + lam x' + x = -F(v - V) + u1 cos(eta t) + u2 cos(nu eta t)`` with the friction law
    ``F(v_r) = x_f sgn(v_r) - b1 v_r + b3 v_r**3`` (x_f = xfk in slip, up to xfs in stick).

    | field | meaning | default |
    |---|---|---|
    | lam | damping ratio c / (m w0), lambda | 0.5 |
    | eta | first tone's frequency over the natural one, w1 / w0 | 0.6 |
    | nu | frequency ratio of the two tones, w2 / w1 | 1.0 |
    | u0 | amplitude of both tones, p0 / (m w0^2) | 0.0 |
    | V | belt speed v0 / w0 | 1.0 |
    | xfk | kinetic friction level mu_k F_N / k | 2.5 |
    | xfs | static friction level mu_s F_N / k (>= xfk) | 4.0 |
    | b1 | linear (viscous) friction coefficient | 0.0 |
    | b3 | cubic (Stribeck-like) friction coefficient | 0.0 |
    | u1 | amplitude of tone 1 if it differs from u0 (None: u0) | None |
    | u2 | amplitude of tone 2 if it differs from u0 (None: u0) | None |

    Defaults are the paper's (Sec. 3.2.1). Construction validates every field and raises
    ``TypeError`` (not a real number) or ``ValueError`` (NaN, infinite, beyond
    ``PARAM_LIMIT`` in magnitude, or out of range) naming the field and its value, so a bad
    run fails before it starts.
    """

    lam: float = 0.5
    eta: float = 0.6
    nu: float = 1.0
    u0: float = 0.0
    V: float = 1.0
    xfk: float = 2.5
    xfs: float = 4.0
    b1: float = 0.0
    b3: float = 0.0
    u1: float | None = None
    u2: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.name in ("u1", "u2"):
                continue
            # TypeError for a non-number (None where a number goes), ValueError for NaN/inf
            # or a magnitude beyond PARAM_LIMIT
            value = check_bounded_real(f.name, value, PARAM_LIMIT)
            object.__setattr__(self, f.name, value)
        checks = (
            ("lam", self.lam >= 0.0, "must be >= 0"),
            ("eta", self.eta > 0.0, "must be > 0"),
            ("nu", self.nu >= 0.0, "must be >= 0"),
            ("u0", self.u0 >= 0.0, "must be >= 0 (a negative amplitude is a phase shift)"),
            ("xfk", self.xfk >= 0.0, "must be >= 0"),
            ("xfs", self.xfs >= self.xfk, f"must be >= xfk = {self.xfk!r}"),
            ("u1", self.u1 is None or self.u1 >= 0.0, "must be >= 0"),
            ("u2", self.u2 is None or self.u2 >= 0.0, "must be >= 0"),
        )
        for name, ok, why in checks:
            if not ok:
                raise ValueError(f"{name} {why}, got {getattr(self, name)!r}")

    # -- derived quantities -------------------------------------------------------------
    @property
    def amp1(self) -> float:
        """Amplitude of the tone at frequency eta."""
        return self.u0 if self.u1 is None else self.u1

    @property
    def amp2(self) -> float:
        """Amplitude of the tone at frequency nu * eta."""
        return self.u0 if self.u2 is None else self.u2

    @property
    def omega1(self) -> float:
        return self.eta

    @property
    def omega2(self) -> float:
        return self.nu * self.eta

    @property
    def is_coulomb(self) -> bool:
        """True when the slip equation is linear, so the closed-form solver applies."""
        return self.b1 == 0.0 and self.b3 == 0.0

    @property
    def law(self) -> str:
        """Name of the friction law if it is one of Fig. 2's, else ``"custom"``."""
        for name, (b1, b3) in FRICTION_LAWS.items():
            if (self.b1, self.b3) == (b1, b3):
                return name
        return "custom"

    # -- constructors -------------------------------------------------------------------
    @classmethod
    def preset(cls, law: str, **overrides: float) -> OscillatorParams:
        """Paper defaults with the friction law of Fig. 2 named by ``law``.

        ``law`` is ``"coulomb"``, ``"viscous"`` (Coulomb + viscosity, b1 = 0.2) or
        ``"stribeck"`` (b1 = 0.2, b3 = 0.16). Keyword overrides replace any field.
        ``TypeError`` naming ``law`` unless it is a str (``str(5)`` would be looked up).
        """
        if not isinstance(law, str):
            raise TypeError(f"law must be a friction law name (str), one of "
                            f"{sorted(FRICTION_LAWS)}, {got(law)}")
        try:
            key = resolve_law(law)
        except ValueError as e:
            raise ValueError(f"law: {e}") from None
        b1, b3 = FRICTION_LAWS[key]
        check_known_fields(cls, overrides, "parameter")
        return cls(**{"b1": b1, "b3": b3, **overrides})

    def replace(self, **changes: float) -> OscillatorParams:
        """A copy with ``changes`` applied (validated like a new instance)."""
        check_known_fields(self, changes, "parameter")
        return replace(self, **changes)

    def to_dict(self) -> dict:
        return asdict(self)

    def to_array(self) -> np.ndarray:
        """The float64 vector the kernels take (layout ``P_*`` in this module)."""
        p = np.empty(N_PARAMS)
        p[P_LAM] = self.lam
        p[P_V] = self.V
        p[P_XFK] = self.xfk
        p[P_XFS] = self.xfs
        p[P_B1] = self.b1
        p[P_B3] = self.b3
        p[P_U1] = self.amp1
        p[P_U2] = self.amp2
        p[P_W1] = self.omega1
        p[P_W2] = self.omega2
        return p
