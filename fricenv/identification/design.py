"""``design_excitation``: the two-tone forcing that makes a record most informative.

The expected Fisher information of a record of ``x`` (sampled every ``dt`` over
``duration``, white noise at ``snr_db``) at a prior plant is ``J^T J / sigma^2``, with
``J`` the exact derivative of the response by the unknowns (the friction law's parameters,
``lam``, and the nuisance start ``x0, v0``). The design maximises a scalar of the
information on the parameters of interest (the start marginalised out): its
log-determinant (``"D"``), minus the sum of relative variances (``"A"``) or the smallest
eigenvalue of the relative information (``"E"``), over the forcing settings within
``bounds``: seeded random candidates first, then a bounded Nelder-Mead polish of the best.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..checks import check_finite_real, check_int, got
from ..params import OscillatorParams
from ..sensitivity import law_wrt
from ..simulate import SimulationError, simulate
from .model import DEFAULT_EXCITATION, noise_sigma, start_state
from .threads import one_blas_thread

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: The settings a design may choose, with their valid ranges (low, high, low open).
DESIGNABLE = {"u0": (0.0, math.inf), "u1": (0.0, math.inf), "u2": (0.0, math.inf),
              "nu": (0.0, math.inf), "eta": (0.0, math.inf)}
CRITERIA = ("D", "A", "E")


def interest(prior: OscillatorParams) -> tuple[str, ...]:
    """The parameters a record should determine by default: lam, the friction levels and
    the law's own (none for Coulomb, b1 for a viscous plant, b1 and b3 for the cubic one,
    vs and cv for the exponential law)."""
    law: tuple[str, ...] = law_wrt(prior)
    if prior.friction is None:
        law = tuple(n for n in law if getattr(prior, n) != 0.0)
    return ("lam", "xfk", "xfs", *law)


def fisher_information(prior: OscillatorParams, duration: float, *, wrt: Sequence[str],
                       snr_db: float = 30.0, dt: float = 0.1,
                       start: tuple[float, float] = (0.3, 1.4)) -> tuple[np.ndarray, float]:
    """The expected Fisher information of an x record of the prior over ``wrt`` plus the
    start ``(x0, v0)`` (last two rows), from the exact Jacobian, and the noise level
    ``sigma`` that ``snr_db`` gives the clean response."""
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    state = start_state(prior, 0.0, *start)
    names = [*wrt, "x0"] + (["v0"] if state.mode != 0 else [])
    tr = simulate(prior, state=state, t_eval=t, wrt=names)
    assert tr.dx_dp is not None
    J = np.nan_to_num(tr.dx_dp, nan=0.0, posinf=0.0, neginf=0.0)
    sigma = noise_sigma(tr.x, snr_db)
    F = J.T @ J / sigma**2
    if state.mode == 0:
        F = np.pad(F, ((0, 1), (0, 1)))
    return F, sigma


def marginal_covariance(F: np.ndarray, k: int) -> np.ndarray:
    """The covariance bound of the first ``k`` parameters, the rest (the start) unknown
    too: the top-left block of ``F^-1`` (pseudo-inverse on a relative scale, so that a
    direction the record misses gives a huge variance, not an error)."""
    s = np.sqrt(np.maximum(np.diag(F), 1e-300))
    lam, vec = np.linalg.eigh(F / np.outer(s, s))
    lam = np.maximum(lam, max(lam.max(), 1e-300) * 1e-16)
    return ((vec / lam) @ vec.T / np.outer(s, s))[:k, :k]


def criterion_value(cov: np.ndarray, values: np.ndarray, criterion: str) -> float:
    """The scalar a design maximises, from the covariance bound of the parameters of
    interest at their prior ``values``: ``-log det`` (D), minus the sum of squared relative
    standard deviations (A), the smallest eigenvalue of the relative information (E)."""
    scale = np.where(values != 0.0, np.abs(values), 1.0)
    rel = cov / np.outer(scale, scale)
    if criterion == "D":
        sign, logdet = np.linalg.slogdet(cov)
        return -logdet if sign > 0 else -math.inf
    if criterion == "A":
        return -float(np.trace(rel))
    return float(1.0 / np.linalg.eigvalsh(rel).max())


def _check_bounds(bounds: object, prior: OscillatorParams) -> dict[str, tuple[float, float]]:
    if not isinstance(bounds, Mapping) or not bounds:
        raise TypeError(f"bounds must be a non-empty dict of setting -> (low, high), for "
                        f"some of {list(DESIGNABLE)}, {got(bounds)}")
    out = {}
    for name, pair in bounds.items():
        if name not in DESIGNABLE:
            raise ValueError(f"bounds: {name!r} is not a forcing setting; expected some of "
                             f"{list(DESIGNABLE)}")
        try:
            lo, hi = (float(b) for b in pair)
        except (TypeError, ValueError):
            raise TypeError(f"bounds[{name!r}] must be a pair (low, high), {got(pair)}") from None
        if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
            raise ValueError(f"bounds[{name!r}] = ({lo!r}, {hi!r}) must be finite with "
                             "low <= high")
        low_valid = DESIGNABLE[name][0]
        if lo < low_valid or (name == "eta" and lo <= 0.0):
            op = ">" if name == "eta" else ">="
            raise ValueError(f"bounds[{name!r}] = ({lo!r}, {hi!r}): {name} must be {op} "
                             f"{low_valid:g}, got low = {lo!r}")
        out[name] = (lo, hi)
    if "u0" in out and ("u1" in out or "u2" in out):
        raise ValueError("bounds: give u0 (both tones) or u1 and u2, not both")
    if ("u1" in out or "u2" in out) and (prior.u1 is None or prior.u2 is None) and not (
            "u1" in out and "u2" in out):
        raise ValueError("bounds on one of u1, u2 need the prior to set both, or bounds "
                         "on both")
    return out


@dataclass
class Design:
    """A designed excitation: the forcing settings (``u0``, ``nu``, ``eta``, or ``u1``,
    ``u2``), the criterion's value, the Cramér-Rao bound of each parameter of interest
    (``crlb``, a standard deviation; ``crlb_relative`` over the prior's value) and the
    Fisher information at the prior."""

    prior: OscillatorParams
    settings: dict[str, float]
    criterion: str
    value: float
    wrt: tuple[str, ...]
    crlb: dict[str, float]
    crlb_relative: dict[str, float]
    fisher: np.ndarray
    duration: float
    snr_db: float
    dt: float
    start: tuple[float, float]
    bounds: dict[str, tuple[float, float]]
    n_evaluations: int
    regime: dict[str, Any] = field(default_factory=dict)

    def __getattr__(self, name: str) -> float:
        """The designed forcing's ``u0``, ``nu``, ``eta`` and the tones' amplitudes
        ``u1``, ``u2`` (``u0`` where the tone follows it)."""
        if name in ("u0", "nu", "eta"):
            return float(getattr(self.plant, name))
        if name in ("u1", "u2"):
            return float(self.plant.amp1 if name == "u1" else self.plant.amp2)
        raise AttributeError(name)

    @property
    def plant(self) -> OscillatorParams:
        """The prior with the designed forcing."""
        return self.prior.replace(**self.settings)

    def covariance(self, settings: Mapping[str, float] | None = None) -> np.ndarray:
        """The covariance bound of the parameters of interest at the prior, with this
        design's forcing or with ``settings`` (the same record length, noise and start)."""
        p = self.plant if settings is None else self.prior.replace(**settings)
        F, _ = fisher_information(p, self.duration, wrt=self.wrt, snr_db=self.snr_db,
                                  dt=self.dt, start=self.start)
        return marginal_covariance(F, len(self.wrt))

    def volume_ratio(self, settings: Mapping[str, float]) -> float:
        """How many times larger the confidence ellipsoid of the parameters of interest is
        with ``settings`` than with this design: ``sqrt(det C_other / det C_design)``."""
        _, a = np.linalg.slogdet(self.covariance(settings))
        _, b = np.linalg.slogdet(self.covariance())
        return float(math.exp(0.5 * (a - b)))

    def compare(self, n_random: int = 20, seed: int = 0) -> dict[str, float]:
        """Volume ratios against the default excitation (:data:`DEFAULT_EXCITATION`), a
        single tone of the design's RMS (amplitude ``sqrt(u1^2 + u2^2)`` at ``eta``) and the
        median of ``n_random`` two-tone designs drawn uniformly within the bounds."""
        p = self.plant
        single = {"u0": 0.0, "u1": math.hypot(p.amp1, p.amp2), "u2": 0.0, "eta": p.eta}
        rng = np.random.default_rng(seed)
        ratios = []
        for _ in range(n_random):
            draw = {n: float(rng.uniform(lo, hi)) for n, (lo, hi) in self.bounds.items()}
            try:
                ratios.append(self.volume_ratio(draw))
            except (SimulationError, ValueError):
                continue
        return {"default": self.volume_ratio(DEFAULT_EXCITATION),
                "single_tone": self.volume_ratio(single),
                "random_median": float(np.median(ratios)) if ratios else math.nan}

    def plot(self, map_size: int = 16) -> Figure:
        """The prior's regime map over (u0, nu) at the design's eta with the design and
        the default excitation marked, the designed response, and the bounds."""
        from .report import design_figure

        return design_figure(self, map_size)


def design_excitation(prior: OscillatorParams, *, duration: float,
                      bounds: Mapping[str, tuple[float, float]], criterion: str = "D",
                      wrt: Sequence[str] | None = None, snr_db: float = 30.0,
                      dt: float = 0.1, start: tuple[float, float] = (0.3, 1.4),
                      n_candidates: int = 48, seed: int = 0) -> Design:
    """The forcing within ``bounds`` that maximises the expected information of an
    ``x`` record of ``duration`` time units on the parameters ``wrt`` of the plant
    ``prior`` (default :func:`interest`).

    ``bounds`` maps forcing settings (``u0``, ``nu``, ``eta``, or ``u1`` and ``u2``) to
    ``(low, high)``; settings not named keep the prior's values. ``criterion`` is ``"D"``
    (log det of the information), ``"A"`` or ``"E"`` (see the module). ``snr_db``, ``dt``
    and ``start`` describe the record the design is for. ``n_candidates`` seeded random
    settings are scored, then the best three are polished by bounded Nelder-Mead.
    Refused, naming the value: bounds outside the settings' valid ranges (u0, u1, u2,
    nu >= 0, eta > 0), a criterion other than D, A, E, a ``wrt`` name the plant has no
    derivative by.
    """
    if not isinstance(prior, OscillatorParams):
        raise TypeError(f"prior must be an OscillatorParams, {got(prior)}")
    duration = check_finite_real("duration", duration)
    if duration <= 0:
        raise ValueError(f"duration must be > 0, got {duration!r}")
    if criterion not in CRITERIA:
        raise ValueError(f"criterion must be one of {list(CRITERIA)}, got {criterion!r}")
    box = _check_bounds(bounds, prior)
    names = tuple(interest(prior) if wrt is None else wrt)
    for name in names:
        if name in ("x0", "v0") or name not in ("lam", "xfk", "xfs", *law_wrt(prior)):
            raise ValueError(f"wrt: {name!r} is not a plant parameter a design can target; "
                             f"expected some of {['lam', 'xfk', 'xfs', *law_wrt(prior)]}")
    check_int("n_candidates", n_candidates, 1)
    values = np.array([getattr(prior, n) for n in names], dtype=np.float64)
    keys = list(box)
    lo = np.array([box[k][0] for k in keys])
    hi = np.array([box[k][1] for k in keys])
    count = [0]

    def score(u: np.ndarray) -> float:
        count[0] += 1
        try:
            p = prior.replace(**dict(zip(keys, np.clip(u, lo, hi).tolist(), strict=True)))
            F, _ = fisher_information(p, duration, wrt=names, snr_db=snr_db, dt=dt,
                                      start=start)
        except (SimulationError, ValueError):
            return -math.inf
        return criterion_value(marginal_covariance(F, len(names)), values, criterion)

    with one_blas_thread():  # (Fisher matrices of a few columns: see .threads)
        best_u, best = _search(score, lo, hi, n_candidates, seed)
    settings = dict(zip(keys, best_u.tolist(), strict=True))
    design = Design(prior, settings, criterion, best, names, {}, {}, np.empty((0, 0)),
                    duration, snr_db, dt, (float(start[0]), float(start[1])), box, count[0])
    F, _ = fisher_information(design.plant, duration, wrt=names, snr_db=snr_db, dt=dt,
                              start=start)
    cov = marginal_covariance(F, len(names))
    sd = np.sqrt(np.diag(cov))
    design.fisher = F
    design.crlb = dict(zip(names, sd.tolist(), strict=True))
    design.crlb_relative = {n: s / abs(v) if v != 0 else math.inf
                            for n, s, v in zip(names, sd, values, strict=True)}
    design.regime = _regime(design.plant, duration, dt, start)
    return design


def _search(score: Any, lo: np.ndarray, hi: np.ndarray, n_candidates: int, seed: int
            ) -> tuple[np.ndarray, float]:
    """Seeded uniform candidates in the box, then bounded Nelder-Mead from the best three."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(seed)
    cands = lo + (hi - lo) * rng.random((n_candidates, lo.size))
    scores = np.array([score(u) for u in cands])
    order = np.argsort(-scores)
    best_u, best = cands[order[0]], float(scores[order[0]])
    free = hi > lo
    if not free.any():
        return lo.copy(), float(score(lo))
    for i in order[: min(3, n_candidates)]:
        if not np.isfinite(scores[i]):
            continue
        sol = minimize(lambda u: -score(u) if np.all(np.isfinite(u)) else math.inf,
                       cands[i], method="Nelder-Mead",
                       bounds=list(zip(lo, hi, strict=True)),
                       options={"maxfev": 40 * lo.size, "xatol": 1e-3, "fatol": 1e-3})
        if -sol.fun > best:
            best_u, best = np.clip(sol.x, lo, hi), float(-sol.fun)
    return best_u, best


def _regime(p: OscillatorParams, duration: float, dt: float, start: tuple[float, float]
            ) -> dict[str, Any]:
    """What the designed record does: stick fraction, stick phases, reversals through the
    belt speed, and whether it slips on both sides of the belt (what separates lam from a
    linear friction term)."""
    t = np.arange(0.0, duration + 0.5 * dt, dt)
    tr = simulate(p, state=start_state(p, 0.0, *start), t_eval=t)
    return {"stick_fraction": tr.stick_fraction, "n_stick": tr.n_stick,
            "n_reversals": tr.n_reversals,
            "slips_above_belt": bool(np.any(tr.mode > 0)),
            "slips_below_belt": bool(np.any(tr.mode < 0))}
