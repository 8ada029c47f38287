"""Model parameters of the two-tone forced mass-on-belt oscillator (paper's Eq. 7)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

import numpy as np

from . import friction
from .checks import check_bounded_real, got
from .friction import FrictionLaw

# Layout of the float64 parameter vector that every kernel takes. Frequencies are stored,
# not (eta, nu), so that a controller may retune a tone without touching the other. The
# friction law is its code (``FrictionLaw.code``) and a block of its own parameters, in the
# order its module declares them (unused slots 0).
P_LAM, P_V, P_XFK, P_XFS, P_U1, P_U2, P_W1, P_W2, P_LAW = range(9)
P_LAW_PARAMS = 9  # first of the law's parameters
N_LAW_PARAMS = 3  # the most any law has
N_PARAMS = P_LAW_PARAMS + N_LAW_PARAMS
# The cubic law's columns (b1, b3), for the environments' draws of a cubic plant.
P_B1 = P_LAW_PARAMS
P_B3 = P_LAW_PARAMS + 1

#: Largest magnitude a parameter may have. The model is dimensionless and its quantities
#: are O(1) in the paper; far beyond that the kernels' squares and cubes of forces
#: overflow (u0 = 1e156 gave a state 2 % off and a NaN (v - V)^2 integral, with no error),
#: and a switching instant, found to rounding of tau (~1e-16), no longer resolves a slip
#: phase as short as 1 / xfk (xfk = 1e20 gave (v - V)^2 integrals 1e13 times too large).
PARAM_LIMIT = 1e12

# The laws a plant without a ``friction`` field has: Coulomb where b1 = b3 = 0, else cubic.
_INFERRED = ("coulomb", "cubic")
#: Named friction laws: the paper's three of Fig. 2 (Coulomb, Coulomb + viscosity, the cubic
#: Stribeck-like law) and the exponential Stribeck law, as the fields they set.
FRICTION_LAWS: dict[str, dict[str, Any]] = {
    name: ({} if law in _INFERRED else {"friction": law}) | values
    for name, (law, values) in friction.PRESETS.items()}
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

# Fields that may be None, and among them a law's parameters (absent unless the law is set).
_OPTIONAL = ("u1", "u2", "vs", "delta", "cv")
_OPTIONAL_LAW = ("friction", "vs", "delta", "cv")
# The fields that name a law and its parameters.
_LAW_FIELDS = ("friction", "b1", "b3", "vs", "delta", "cv")

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


#: Fastest relaxation of slip, |dv'/dv| near the belt speed (``FrictionLaw.stiffness``),
#: that the event method runs: its Taylor steps are about 2.5 / |dv'/dv| long, and a
#: recorded run takes Taylor steps only, so past this a unit of time needs over 4e4 steps.
#: Measured on ``OscillatorParams(b1=b, u0=5, nu=1)`` over 100 units: ``run_stats`` and ``simulate``
#: agreed to 2e-5 in the stick fraction up to b = -1e5 (1.1 s); at b = -1e6 ``simulate``
#: ran out of its step budget, and from b = -1e7 both did, or blamed chattering.
SLIP_STIFFNESS_LIMIT = 1e5


def law_stiffness(P: np.ndarray) -> np.ndarray:
    """Each row's slip stiffness (``FrictionLaw.stiffness``) where the event method runs
    its law, 0 where the closed form does (rows of ``P``, last axis the layout ``P_*``)."""
    P = np.asarray(P, dtype=np.float64)
    out = np.zeros(P.shape[:-1])
    codes = P[..., P_LAW]
    if P.ndim == 2 and P.shape[0] == 1:  # (every run checks its row: spare the masks)
        law = friction.law_of_code(codes[0])
        if not law.closed_form:
            row = P[0]
            out[0] = law.stiffness(
                {p.name: float(row[P_LAW_PARAMS + i]) for i, p in enumerate(law.params)},
                float(row[P_LAM]), float(row[P_XFK]), float(row[P_XFS]))
        return out
    for law in friction.LAWS.values():
        rows = codes == law.code
        if law.closed_form or not np.any(rows):
            continue
        values = {p.name: P[..., P_LAW_PARAMS + i][rows] for i, p in enumerate(law.params)}
        out[rows] = law.stiffness(values, P[..., P_LAM][rows], P[..., P_XFK][rows],
                                  P[..., P_XFS][rows])
    return out


def law_envelope(P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(level, b1, b3)`` of parameter rows ``P`` (last axis the layout ``P_*``): a
    Coulomb-plus-cubic law that bounds each row's friction law
    (``FrictionLaw.envelope``), for the divergence bound."""
    P = np.asarray(P, dtype=np.float64)
    shape = P.shape[:-1]
    level, b1, b3 = (np.zeros(shape) for _ in range(3))
    codes = P[..., P_LAW]
    for law in friction.LAWS.values():
        rows = codes == law.code
        if not np.any(rows):
            continue
        values = {p.name: P[..., P_LAW_PARAMS + i][rows] for i, p in enumerate(law.params)}
        lv, l1, l3 = law.envelope(values, P[..., P_XFK][rows], P[..., P_XFS][rows])
        level[rows], b1[rows], b3[rows] = lv, l1, l3
    return level, b1, b3


def check_known_fields(cls_or_obj: Any, names: Iterable[str], what: str) -> None:
    """``ValueError`` listing the names that are not fields of a dataclass, and the valid ones."""
    known = {f.name for f in fields(cls_or_obj)}
    unknown = sorted(set(names) - known)
    if unknown:
        raise ValueError(f"unknown {what}(s) {unknown}; expected some of {sorted(known)}")


@dataclass(frozen=True)
class OscillatorParams:
    """Dimensionless parameters of the paper's Eq. 7.

    ``x'' + lam x' + x = -F(v - V) + u1 cos(eta t) + u2 cos(nu eta t)`` with a friction law
    ``F(v_r)`` in slip (the block sticks while the other forces stay within ``xfs``). The law
    is named by ``friction`` (:data:`fricenv.friction.LAWS`); left at None, it is the
    paper's ``F(v_r) = xfk sgn(v_r) - b1 v_r + b3 v_r**3``: ``"coulomb"`` where
    ``b1 = b3 = 0``, else ``"cubic"``. ``"exponential"`` is the exponential Stribeck law
    ``F = sgn(v_r) (xfk + (xfs - xfk) exp(-(|v_r| / vs)^delta)) + cv v_r``.

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
    | friction | the friction law's name (None: coulomb or cubic, from b1 and b3) | None |
    | vs | Stribeck speed of the exponential law | None (0.4 with that law) |
    | delta | its shape exponent, 1 or 2 | None (2 with that law) |
    | cv | its viscous coefficient, >= 0 | None (0.05 with that law) |

    A law's own parameters are valid only with that law: ``b1 = 0.2`` with the exponential
    law, or ``vs`` without it, is refused naming the field.

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
    friction: str | None = None
    vs: float | None = None
    delta: float | None = None
    cv: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.name in _OPTIONAL:
                continue
            if f.name == "friction":
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
        self._check_law()

    def _check_law(self) -> None:
        """Fill the law's parameters left at None with its defaults and check them; refuse a
        parameter of another law (ValueError naming it)."""
        if self.friction is not None and not isinstance(self.friction, str):
            raise TypeError(f"friction must be a friction law's name (str) or None, "
                            f"{got(self.friction)}")
        law = self.law_spec
        for name, owner in friction.OWNER.items():
            value = getattr(self, name)
            if owner != law.name and owner not in (_INFERRED if law.name in _INFERRED
                                                   else ()) and value not in (None, 0.0):
                raise ValueError(f"{name} belongs to the {owner} law, but this plant's law "
                                 f"is {law.name}, got {name}={value!r}")
        for p in law.params:
            if getattr(self, p.name) is None:
                object.__setattr__(self, p.name, p.default)
        law.check(self.law_values())
        # the kernels' vector, once: the instance is frozen, and every run asks for it
        object.__setattr__(self, "_array", self._build_array())

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
    def law_spec(self) -> FrictionLaw:
        """The friction law (:class:`fricenv.friction.FrictionLaw`)."""
        if self.friction is None:
            return friction.polynomial_law(self.b1, self.b3)
        return friction.law_named(self.friction)

    def law_values(self) -> dict[str, float]:
        """The friction law's own parameters by name."""
        return {p.name: float(getattr(self, p.name)) for p in self.law_spec.params}

    @property
    def is_coulomb(self) -> bool:
        """True when the law's slip equation is linear, so the closed-form solver applies."""
        return self.law_spec.closed_form

    @property
    def law(self) -> str:
        """Name of the friction law if it is a named one (:data:`FRICTION_LAWS`), else
        ``"custom"``."""
        mine = {k: v for k, v in self.to_dict().items()
                if k in _LAW_FIELDS and v is not None and v != 0.0}
        for name, fields_ in FRICTION_LAWS.items():
            if mine == {k: v for k, v in fields_.items() if v != 0.0}:
                return name
        return "custom"

    # -- constructors -------------------------------------------------------------------
    @classmethod
    def preset(cls, law: str, **overrides: Any) -> OscillatorParams:
        """Paper defaults with the friction law of Fig. 2 named by ``law``.

        ``law`` is ``"coulomb"``, ``"viscous"`` (Coulomb + viscosity, b1 = 0.2),
        ``"stribeck"`` (b1 = 0.2, b3 = 0.16) or ``"exponential"`` (vs = 0.4, delta = 2,
        cv = 0.05). Keyword overrides replace any field.
        ``TypeError`` naming ``law`` unless it is a str (``str(5)`` would be looked up).
        """
        if not isinstance(law, str):
            raise TypeError(f"law must be a friction law name (str), one of "
                            f"{sorted(FRICTION_LAWS)}, {got(law)}")
        try:
            key = resolve_law(law)
        except ValueError as e:
            raise ValueError(f"law: {e}") from None
        check_known_fields(cls, overrides, "parameter")
        return cls(**{**FRICTION_LAWS[key], **overrides})

    def replace(self, **changes: Any) -> OscillatorParams:
        """A copy with ``changes`` applied (validated like a new instance)."""
        check_known_fields(self, changes, "parameter")
        return replace(self, **changes)

    def to_dict(self) -> dict:
        """The fields by name; the exponential law's fields only where it is the law."""
        return {k: v for k, v in asdict(self).items() if not (k in _OPTIONAL_LAW and v is None)}

    def plan_fields(self) -> tuple[str, ...]:
        """The fields a regime-map cell's time spans depend on beside nu: eta, lam and what
        the law's damping of slip near the belt speed reads."""
        if self.friction is None:
            return ("eta", "lam", "b1")
        return ("eta", "lam", "xfk", "xfs", *self.law_spec.param_names)

    def law_rows(self, values: dict[str, np.ndarray], n: int) -> np.ndarray:
        """The law code and parameter columns (``P[:, P_LAW:]``) of ``n`` plants that are
        this one with the law parameters in ``values`` (1-d arrays) changed; ``ValueError``
        naming a parameter of another law, or a value out of its range."""
        law = self.law_spec
        out = np.repeat(self.to_array()[None, P_LAW:], n, axis=0)
        own = (("b1", "b3") if self.friction is None else law.param_names)
        for name in (k for k in values if k in friction.OWNER):
            if name not in own:
                raise ValueError(f"{name} belongs to the {friction.OWNER[name]} law, but the "
                                 f"plants' law is {law.name}")
            out[:, 1 + own.index(name)] = values[name]
        if self.friction is None:
            out[:, 0] = np.where((out[:, 1] == 0.0) & (out[:, 2] == 0.0),
                                 friction.LAWS["coulomb"].code, friction.LAWS["cubic"].code)
        else:
            for p in law.params:
                if p.name in values:
                    for v in np.unique(values[p.name]):
                        p.check(float(v), law.name)
        return out

    def to_array(self) -> np.ndarray:
        """The float64 vector the kernels take (layout ``P_*`` in this module), a copy."""
        return self._array.copy()  # type: ignore[attr-defined]

    def _build_array(self) -> np.ndarray:
        p = np.empty(N_PARAMS)
        p[P_LAM] = self.lam
        p[P_V] = self.V
        p[P_XFK] = self.xfk
        p[P_XFS] = self.xfs
        p[P_LAW] = self.law_spec.code
        p[P_LAW_PARAMS:] = 0.0
        for i, value in enumerate(self.law_values().values()):
            p[P_LAW_PARAMS + i] = value
        p[P_U1] = self.amp1
        p[P_U2] = self.amp2
        p[P_W1] = self.omega1
        p[P_W2] = self.omega2
        return p
