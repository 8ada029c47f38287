"""``identify``: which friction law, with which parameters, produced a measured record.

Each candidate law is fitted by output-error least squares on the exact simulator:
``scipy.optimize.least_squares`` (trust region, bounds) minimises the misfit between the
record and the simulated response from several starts, with the exact Jacobian the
simulator's forward sensitivities give through every stick/slip switch. The friction is
never smoothed. The laws are then ranked by BIC. Intervals come from the Fisher
information of the fit (the Gauss-Newton matrix ``J^T J / sigma^2``), which is also the
Cramér-Rao bound at the estimate; a parameter the record cannot pin down is flagged with
the reason instead of being reported as a confident number.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..layout import EVENT_REVERSAL, EVENT_SLIP
from ..params import OscillatorParams
from .model import (
    LOWER,
    SCALE_FLOOR,
    LawModel,
    SimulationError,
    first_period,
    noise_level,
    response,
)

#: Two-sided 95 % normal quantile.
Z95 = 1.959963984540054
#: Residual given to a trial point where the simulator refuses to run (a divergent plant):
#: large, finite, so that the trust region shrinks its step instead of failing.
_PENALTY = 1e3
#: Forcing periods of the record's start that each start is first fitted to; the horizon
#: then grows by :data:`HORIZON_GROWTH` per step up to the whole record.
SHORT_PERIODS = 2.0
#: Growth of the horizon per continuation step. Each step adds the few stick/slip switches
#: that the previous step's estimate can still predict: doubling the horizon added, on the
#: benchmark's designed records, a short stick that the estimate missed, and the fit then
#: stopped at twice the noise level (a kink of the cost, where the missing switch has no
#: gradient); growing by a quarter per step cost about 15 evaluations of short records more.
HORIZON_GROWTH = 1.25
#: A fit whose residual's RMS exceeds this multiple of the record's noise level
#: (:func:`~fricenv.identification.model.noise_level`, itself within 8 %) has stopped in a
#: local minimum: a switch of the record is missing from the fitted motion, or one is too
#: many. Fits at the global minimum of a law that can produce the record sit at 0.95-1.05.
RESCUE_RATIO = 1.2
#: Perturbed restarts drawn per rescue, and their spread in standard deviations of the
#: previous horizon's estimate.
RESCUE_DRAWS, RESCUE_SPREAD = 16, (1.5, 4.0)
#: Evaluations each perturbed restart gets before it is judged: one in the right basin
#: reaches the noise level within 4-15 (measured on the benchmark's designed records); the
#: best is then finished with the fit's full budget.
RESCUE_NFEV = 25
#: Where another law already fits the record at its noise level, a law whose first start
#: ends at more than this multiple of the noise level gets no further starts: its BIC is
#: then hundreds of units behind, and its starts differ only in where they begin (on a
#: Coulomb record, the exponential law's second start cost a third of identify's time
#: and ended where the first did). A nested law is refitted from its neighbour's estimate
#: anyway (``identify``).
FAR_RATIO = 2.0


def _scipy_least_squares() -> Any:
    try:
        from scipy.optimize import least_squares
    except ImportError:  # pragma: no cover - scipy is in the identify extra
        raise ImportError("identify needs SciPy: pip install 'fricenv[identify]'") from None
    return least_squares


@dataclass
class LawFit:
    """One candidate law fitted to the record.

    ``estimates``/``se``/``ci`` are by natural name (``lam``, ``xfk``, ``xfs``, the law's,
    ``x0``, ``v0``); ``crlb`` is the Cramér-Rao bound (standard deviation) at the estimate
    and estimated noise, ``sqrt(diag(F^-1))`` with ``F = J^T J / sigma^2`` from the exact
    Jacobian. ``undetermined`` maps each parameter the record cannot pin down to the
    reason; ``combinations`` lists what is determined instead (name, coefficients,
    value, standard error). ``events`` is the fitted stick/slip sequence.
    """

    law: str
    names: tuple[str, ...]
    estimates: dict[str, float]
    se: dict[str, float]
    ci: dict[str, tuple[float, float]]
    crlb: dict[str, float]
    sigma: dict[str, float]
    loglik: float
    bic: float
    n_obs: int
    residuals: np.ndarray
    fitted_x: np.ndarray
    fitted_v: np.ndarray
    events: np.ndarray
    fisher: np.ndarray
    fisher_eigenvalues: np.ndarray
    undetermined: dict[str, str]
    combinations: list[dict[str, Any]]
    converged: bool
    message: str
    n_starts: int
    n_evaluations: int
    seconds: float
    params: OscillatorParams
    starts_cost: list[float] = field(default_factory=list)
    #: The sides of the belt speed on which the fitted motion slips: -1 below it, +1 above
    #: (:func:`slip_sides`).
    slip_sides: tuple[int, ...] = ()
    #: The record's noise level in x, read off the record without a model
    #: (:func:`~fricenv.identification.model.noise_level`).
    noise: float = math.nan

    @property
    def residual_ratio(self) -> float:
        """The x residual's RMS over :attr:`noise`: near 1 where the law fits the record
        down to its noise, far above 1 where it does not (or where the fit stopped at a
        kink of the cost)."""
        return self.sigma["x"] / self.noise

    @property
    def k(self) -> int:
        """Number of estimated quantities, the noise levels included (what BIC counts)."""
        return len(self.names) + len(self.sigma)


def _initial_state(t: np.ndarray, x: np.ndarray, v: np.ndarray | None) -> tuple[float, float]:
    """x0 and v0 from the record's first samples: a quadratic through about a tenth of a
    time unit's worth (at least 5 samples) smooths the noise of a velocity by differences."""
    if v is not None:
        return float(x[0]), float(v[0])
    n = max(5, int(np.searchsorted(t, t[0] + 0.3)))
    c = np.polyfit(t[:n] - t[0], x[:n], 2)
    return float(c[2]), float(c[1])


def _starts(model: LawModel, x0v0: tuple[float, float], n_starts: int,
            rng: np.random.Generator, seeds: Sequence[Mapping[str, float]]
            ) -> list[np.ndarray]:
    """The starts: the law's preset values, each seed (another law's fit, with this law's
    own parameters at their presets), then draws around the preset (log-normal factors,
    25 %-100 % spread) until ``n_starts``."""
    base = model.default_values() | {"x0": x0v0[0], "v0": x0v0[1]}
    starts = [model.to_internal(base)]
    for s in seeds:
        starts.append(model.to_internal(base | {k: s[k] for k in ("lam", "xfk", "xfs")}))
    lo, _ = model.bounds()
    while len(starts) < n_starts:
        z = starts[0].copy()
        spread = 0.25 + 0.75 * rng.random()
        for i, name in enumerate(model.names):
            if name in ("x0", "v0"):
                continue
            scale = abs(z[i]) if z[i] != 0.0 else SCALE_FLOOR.get(name, 0.1)
            z[i] = max(z[i] * math.exp(spread * rng.standard_normal())
                       if z[i] != 0.0 else scale * rng.standard_normal(), lo[i])
        starts.append(z)
    return starts[:max(n_starts, 1 + len(seeds))]


class _Objective:
    """Residuals and exact Jacobian of one candidate, cached per point (least_squares asks
    for both at the same point)."""

    def __init__(self, model: LawModel, t: np.ndarray, x: np.ndarray, v: np.ndarray | None,
                 weights: tuple[float, float]) -> None:
        self.model, self.t, self.x, self.v, self.w = model, t, x, v, weights
        self.M = model.jac_map()
        self._key: bytes | None = None
        self._r = np.empty(0)
        self._J = np.empty((0, 0))
        self.n_eval = 0
        self.n_singular = 0

    def _eval(self, z: np.ndarray) -> None:
        key = z.tobytes()
        if key == self._key:
            return
        self.n_eval += 1
        n = self.t.size * (1 if self.v is None else 2)
        try:
            res = response(self.model, self.model.to_natural(z), self.t)
        except (SimulationError, ValueError):
            self._r = np.full(n, _PENALTY)
            self._J = np.zeros((n, self.model.k))
        else:
            r = [(res.x - self.x) * self.w[0]]
            J = [res.dx @ self.M * self.w[0]]
            if self.v is not None:
                r.append((res.v - self.v) * self.w[1])
                J.append(res.dv @ self.M * self.w[1])
            self._r, self._J = np.concatenate(r), np.vstack(J)
            self.n_singular = res.n_singular
            if res.undefined is not None:
                self._secant_rows(z, res.undefined)
        self._key = key

    def _secant_rows(self, z: np.ndarray, undefined: np.ndarray) -> None:
        """Central differences (step 1e-5 of each parameter's scale) for the samples past
        a point where the exact derivative does not exist (a tangential break-away, a
        grazing contact). There the cost has a kink; a Jacobian of zeros would tell the
        optimiser that a quarter of the record does not depend on the parameters, and it
        would stall on the kink (measured: a viscous fit stopped at cost 1.113 against
        1.054 at the truth)."""
        rows = np.concatenate([undefined] * (1 if self.v is None else 2))
        lo, hi = self.model.bounds()
        for j, name in enumerate(self.model.names):
            h = 1e-5 * max(abs(z[j]), SCALE_FLOOR.get(name, 0.1))
            zp, zm = z.copy(), z.copy()
            zp[j] = min(z[j] + h, hi[j])
            zm[j] = max(z[j] - h, lo[j])
            cols = []
            for zz in (zp, zm):
                try:
                    res = response(self.model, self.model.to_natural(zz), self.t,
                                   jacobian=False)
                except (SimulationError, ValueError):
                    break
                r = [(res.x - self.x) * self.w[0]]
                if self.v is not None:
                    r.append((res.v - self.v) * self.w[1])
                cols.append(np.concatenate(r))
            if len(cols) == 2 and zp[j] > zm[j]:
                self._J[rows, j] = (cols[0] - cols[1])[rows] / (zp[j] - zm[j])

    def residuals(self, z: np.ndarray) -> np.ndarray:
        self._eval(z)
        return self._r

    def cost(self, z: np.ndarray) -> float:
        """Half the sum of squared residuals at ``z``, without the Jacobian (a screen of
        candidate starts); the penalty's where the simulator refuses."""
        try:
            res = response(self.model, self.model.to_natural(z), self.t, jacobian=False)
        except (SimulationError, ValueError):
            return 0.5 * self.t.size * (1 if self.v is None else 2) * _PENALTY ** 2
        c = float(np.sum(((res.x - self.x) * self.w[0]) ** 2))
        if self.v is not None:
            c += float(np.sum(((res.v - self.v) * self.w[1]) ** 2))
        return 0.5 * c

    def rms_x(self, sol: Any) -> float:
        """RMS of the x residual at a solution of this objective, in x's units."""
        r = np.asarray(sol.fun)[:self.t.size]
        return float(np.sqrt(np.mean(r * r))) / self.w[0]

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        self._eval(z)
        return self._J


def _solve(obj: _Objective, starts: list[np.ndarray], max_nfev: int,
           horizons: Sequence[_Objective] = (), noise: float | None = None,
           rng: np.random.Generator | None = None, explained: bool = False
           ) -> tuple[Any, list[float]]:
    """least_squares from each start, until two starts agree on the lowest cost or one
    reaches the record's noise level (or, where another law is ``explained`` the record,
    this law's best ends beyond :data:`FAR_RATIO` times it); the best result, and the
    final cost of every start.

    With ``horizons`` (the same fit on growing prefixes of the record, shortest first),
    each start is first fitted on the shortest (:func:`_short_start`), then carried
    through the longer ones and the whole record (:func:`_extend`): the stick/slip
    sequence of a long record is caught a few switches at a time, where a fit of the
    whole record from afar lands on a sequence with switches missing. Once a horizon's fit
    stays above the noise level, the law does not follow the record, and the start goes
    straight to the whole record (on a Coulomb record, the exponential law spent 12 s
    on the horizons between)."""
    lo, hi = obj.model.bounds()
    best, costs = None, []
    for z0 in starts:
        if best is not None and (
                sum(abs(c - best.cost) <= 1e-5 * best.cost for c in costs) >= 2
                or _at_noise(obj, best, noise)
                or explained and noise is not None and obj.rms_x(best) > FAR_RATIO * noise):
            break  # the rest would find the same minimum again
        z0 = np.clip(z0, lo, hi)
        if horizons:
            sol = _short_start(horizons[0], z0, lo, hi, max_nfev)
            prev_h = horizons[0]
            for h in (*horizons[1:], obj):
                if h is not obj and noise is not None and not _at_noise(prev_h, sol, noise):
                    continue  # the law does not follow the record: straight to the whole
                sol = _extend(h, sol, lo, hi, max_nfev, noise, rng,
                              _at_noise(prev_h, sol, noise), final=h is obj)
                prev_h = h
        else:
            sol = _least_squares(obj, z0, lo, hi, max_nfev)
        costs.append(float(sol.cost))
        if best is None or sol.cost < best.cost:
            best = sol
    return best, costs


def _at_noise(obj: _Objective, sol: Any, noise: float | None) -> bool:
    """Whether ``sol`` fits ``obj``'s record down to its noise level (:data:`RESCUE_RATIO`)."""
    return noise is not None and obj.rms_x(sol) <= RESCUE_RATIO * noise


def _extend(obj: _Objective, prev: Any, lo: np.ndarray, hi: np.ndarray, max_nfev: int,
            noise: float | None, rng: np.random.Generator | None, prev_at_noise: bool,
            final: bool = False) -> Any:
    """The fit on ``obj``'s horizon from ``prev``, the fit on a shorter one.

    Where ``prev`` fitted its horizon down to the noise level but this fit stays far above
    it, a switch that the added stretch holds is missing from the fitted motion (or one
    is too many), and no gradient leads to it (a kink of the cost): perturbed copies of
    ``prev`` are drawn from its own uncertainty (:data:`RESCUE_DRAWS` at each spread of
    :data:`RESCUE_SPREAD` standard deviations), screened by their cost, and the two best
    are fitted; the lowest cost is kept. On the whole record (``final``) one round of
    perturbed restarts runs even at the noise level: a switch missed by a short stick
    raises the residual by a few per cent only (measured: a viscous fit at 1.02 times the
    noise level, 6.5 standard deviations off in xfk; from the perturbed restart, 0.8).
    A law that could not follow ``prev``'s horizon gets no restarts: it does not hold the
    record, and more starts would not change that."""
    sol = _least_squares(obj, np.asarray(prev.x), lo, hi, max_nfev)
    if noise is None or rng is None or not prev_at_noise or (
            not final and _at_noise(obj, sol, noise)):
        return sol
    root = _uncertainty_root(obj.model, prev)
    z_prev = np.asarray(prev.x)
    cap = 0.5 * np.maximum(np.abs(z_prev), [SCALE_FLOOR.get("xfs" if i == 2 else n, 0.1)
                                            for i, n in enumerate(obj.model.names)])
    for spread in RESCUE_SPREAD:
        draws = []
        for _ in range(RESCUE_DRAWS):
            step = np.clip(spread * (root @ rng.standard_normal(z_prev.size)), -cap, cap)
            z = np.clip(z_prev + step, lo, hi)
            draws.append((obj.cost(z), z))
        draws.sort(key=lambda d: d[0])
        for _, z in draws[:2]:
            trial = _least_squares(obj, z, lo, hi, min(max_nfev, RESCUE_NFEV))
            if trial.cost < sol.cost:
                sol = trial
        if obj.rms_x(sol) <= RESCUE_RATIO * noise:
            break
    if sol.status == 0:  # a restart that ran out of its evaluations: finish it
        sol = _least_squares(obj, np.asarray(sol.x), lo, hi, max_nfev)
    return sol


def _uncertainty_root(model: LawModel, sol: Any) -> np.ndarray:
    """``R`` with ``R R^T`` the covariance of a least-squares solution (Gauss-Newton, the
    residual's own scale), in the internal coordinates: a standard normal draw times
    ``R`` is a draw of the estimate's uncertainty. Directions the record does not
    determine get a huge spread, which the caller caps."""
    J = np.asarray(sol.jac)
    m, k = J.shape
    s2 = 2.0 * float(sol.cost) / max(m - k, 1)
    F = J.T @ J / max(s2, 1e-300)
    d = np.sqrt(np.maximum(np.diag(F), 1e-300))
    lam, vec = np.linalg.eigh(F / np.outer(d, d))
    lam = np.maximum(lam, max(float(lam.max()), 1e-300) * 1e-12)
    return (vec / np.sqrt(lam)) / d[:, None]


def _reversal_forces(model: LawModel, values: dict[str, float], tr: Any) -> np.ndarray:
    """The friction force that would have held the block at each reversal through the
    belt speed of ``tr`` (the block passes v = V without sticking only where it exceeds
    xfs)."""
    ev = tr.events
    rev = ev[ev["kind"] == EVENT_REVERSAL]
    p = model.plant(values)
    return np.abs(p.amp1 * np.cos(p.omega1 * rev["t"]) + p.amp2 * np.cos(p.omega2 * rev["t"])
                  - rev["x"] - p.lam * p.V)


def slip_sides(model: LawModel, values: dict[str, float], tr: Any,
               since: float = -math.inf) -> tuple[int, ...]:
    """The sides of the belt speed on which the motion ``tr`` slips from time ``since``
    on (-1 below, +1 above): the modes at the samples, the direction of every break-away
    (the sign of the force that held the block just before it, so that a slip shorter
    than the sampling counts too), and both sides if it ever passes through the belt
    speed without sticking."""
    sides = {int(m) for m in np.unique(tr.mode[tr.t >= since]) if m != 0}
    ev = tr.events
    ev = ev[ev["t"] >= since]
    if np.any(ev["kind"] == EVENT_REVERSAL):
        return (-1, 1)
    brk = ev[ev["kind"] == EVENT_SLIP]
    if brk.size:
        p = model.plant(values)
        held = (p.amp1 * np.cos(p.omega1 * brk["t"]) + p.amp2 * np.cos(p.omega2 * brk["t"])
                - brk["x"] - p.lam * p.V)
        sides |= {int(np.sign(f)) for f in held if f != 0.0}
    return tuple(sorted(sides))


#: Start velocities tried on the short record, relative to the belt speed (in units of
#: max(1, |V|)), beside the one the record's first samples suggest and its mirror about V.
V0_OFFSETS = (-1.5, -0.75, -0.25, 0.25, 0.75, 1.5)


def _short_start(short: _Objective, z0: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 max_nfev: int) -> Any:
    """A start refined on the record's first periods. The start velocity that a noisy
    record's first samples suggest is poor (at 30 dB, off by 1 from 1.4), and a fit
    cannot carry v0 across the belt speed: the derivative by v0 vanishes at v0 = V, where
    the block starts stuck. So several v0 on both sides of V are scored, and the two
    best are fitted on the short record; the better fit is returned."""
    V = short.model.base.V
    cands = []
    for v0 in (z0[-1], 2.0 * V - z0[-1], *(V + d * max(1.0, abs(V)) for d in V0_OFFSETS)):
        z = z0.copy()
        z[-1] = v0
        cands.append((short.cost(z), z))
    cands.sort(key=lambda c: c[0])
    fits = [_least_squares(short, z, lo, hi, max(20, max_nfev // 2)) for _, z in cands[:2]]
    return min(fits, key=lambda sol: sol.cost)


def _least_squares(obj: _Objective, z0: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                   max_nfev: int) -> Any:
    least_squares = _scipy_least_squares()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return least_squares(obj.residuals, z0, jac=obj.jacobian, bounds=(lo, hi),
                             method="trf", x_scale="jac", max_nfev=max_nfev,
                             ftol=1e-8, xtol=1e-8, gtol=1e-8)


def fit_law(law: str, t: np.ndarray, x: np.ndarray, v: np.ndarray | None,
            known: Mapping[str, float], *, n_starts: int = 3, max_nfev: int = 100,
            rng: np.random.Generator | None = None,
            seeds: Sequence[Mapping[str, float]] = (),
            warm: Mapping[str, float] | None = None, explained: bool = False) -> LawFit:
    """Fit one candidate law to a checked record (see :func:`identify`). ``warm`` (values
    of every estimated name) replaces the starts by that one point, fitted on the whole
    record at once: a refit from a neighbouring law's estimate. ``explained``: another
    law already fits the record at its noise level (see :data:`FAR_RATIO`)."""
    t_start = time.perf_counter()
    rng = np.random.default_rng(0) if rng is None else rng
    model = LawModel.make(law, known)
    x0v0 = _initial_state(t, x, v)
    # first pass weights from the record's spread, then from the residuals of the best fit
    weights = (1.0 / max(float(np.std(x)), 1e-12),
               1.0 / max(float(np.std(v)), 1e-12) if v is not None else 0.0)
    obj = _Objective(model, t, x, v, weights)
    horizons = []
    periods = SHORT_PERIODS
    while True:
        m = int(np.searchsorted(t, t[0] + periods * first_period(known)))
        if m * HORIZON_GROWTH >= t.size:
            break
        if m >= 8:
            horizons.append(_Objective(model, t[:m], x[:m], None if v is None else v[:m],
                                       weights))
        periods *= HORIZON_GROWTH
    noise = noise_level(t, x)
    if warm is not None:
        sol, costs = _solve(obj, [model.to_internal(warm)], max_nfev)
    else:
        sol, costs = _solve(obj, _starts(model, x0v0, n_starts, rng, seeds), max_nfev,
                            horizons, noise, rng, explained)
    sigma = _sigmas(model, sol.x, t, x, v)
    if v is not None:  # refine with the channels weighted by their noise levels
        obj.w = (1.0 / sigma["x"], 1.0 / sigma["v"])
        sol2, _ = _solve(obj, [np.asarray(sol.x)], max_nfev)
        sol = sol2
        sigma = _sigmas(model, sol.x, t, x, v)
    fit = _assemble(model, obj, sol, sigma, t, x, v, costs, len(costs),
                    time.perf_counter() - t_start)
    fit.noise = noise
    return fit


def _sigmas(model: LawModel, z: np.ndarray, t: np.ndarray, x: np.ndarray,
            v: np.ndarray | None) -> dict[str, float]:
    """Maximum-likelihood noise level of each measured channel at the estimate."""
    res = response(model, model.to_natural(z), t, jacobian=False)
    out = {"x": float(np.sqrt(np.mean((res.x - x) ** 2)))}
    if v is not None:
        out["v"] = float(np.sqrt(np.mean((res.v - v) ** 2)))
    return {k: max(s, 1e-15) for k, s in out.items()}


def _assemble(model: LawModel, obj: _Objective, sol: Any, sigma: dict[str, float],
              t: np.ndarray, x: np.ndarray, v: np.ndarray | None, costs: list[float],
              n_starts: int, seconds: float) -> LawFit:
    """Everything a fit reports, from the optimiser's solution."""
    values = model.to_natural(sol.x)
    res = response(model, values, t)
    J = [res.dx / sigma["x"]]
    resid = [x - res.x]
    if v is not None:
        J.append(res.dv / sigma["v"])
        resid.append(v - res.v)
    Jn = np.vstack(J)
    fisher = Jn.T @ Jn
    cov, dead = _covariance(fisher)
    se = {n: float(math.sqrt(max(cov[i, i], 0.0))) if i not in dead else math.inf
          for i, n in enumerate(model.names)}
    ci = {n: (values[n] - Z95 * se[n], values[n] + Z95 * se[n]) for n in model.names}
    undetermined, combos = _identifiability(model, values, se, cov, dead, res.trajectory, ci)
    if combos:
        _widen_along_valley(model, obj, sol.x, cov, ci, t.size)
    for name, low in LOWER.items():  # an interval never reaches below a valid value
        if name in ci:
            ci[name] = (max(ci[name][0], low), max(ci[name][1], low))
    n_obs = t.size * (1 if v is None else 2)
    loglik = -0.5 * sum(t.size * (math.log(2 * math.pi * s * s) + 1.0) for s in sigma.values())
    k = model.k + len(sigma)
    converged = bool(sol.status > 0) and obj.n_eval > 0 and float(sol.cost) < 0.5 * _PENALTY ** 2
    message = str(sol.message) if converged else (
        f"did not converge: {sol.message} (after {sol.nfev} evaluations; raise max_nfev "
        "or give a longer record)")
    tr: Any = res.trajectory
    return LawFit(
        law=model.law, names=model.names, estimates=values, se=se, ci=ci, crlb=dict(se),
        sigma=sigma, loglik=loglik, bic=k * math.log(n_obs) - 2.0 * loglik, n_obs=n_obs,
        residuals=np.stack(resid, axis=1), fitted_x=res.x, fitted_v=res.v,
        events=tr.events, fisher=fisher,
        fisher_eigenvalues=np.sort(np.linalg.eigvalsh(fisher))[::-1],
        undetermined=undetermined, combinations=combos, converged=converged,
        message=message, n_starts=n_starts, n_evaluations=obj.n_eval, seconds=seconds,
        params=model.plant(values), starts_cost=costs, slip_sides=slip_sides(model, values, tr))


def _covariance(fisher: np.ndarray) -> tuple[np.ndarray, set[int]]:
    """The inverse Fisher matrix, and the parameters the record does not depend on at all
    (zero column): those are left out of the inverse, their variance infinite."""
    scale = np.sqrt(np.diag(fisher))
    dead = {i for i in range(fisher.shape[0]) if scale[i] <= 1e-12 * max(scale.max(), 1e-300)}
    live = [i for i in range(fisher.shape[0]) if i not in dead]
    cov = np.full(fisher.shape, np.inf)
    if live:
        sub = fisher[np.ix_(live, live)]
        s = scale[live]
        lam, vec = np.linalg.eigh(sub / np.outer(s, s))
        lam = np.maximum(lam, lam.max() * 1e-16)
        cov[np.ix_(live, live)] = (vec / lam) @ vec.T / np.outer(s, s)
    return cov, dead


def _dead_reason(name: str, tr: Any) -> str:
    n_stick = int(tr.stats.n_stick) + (1 if tr.mode.size and tr.mode[0] == 0 else 0)
    if name == "xfs":
        if n_stick == 0:
            return ("the fitted motion never sticks, so static friction never acts on it: "
                    "xfs is only known to lie above xfk (and below the friction force at "
                    "each reversal through the belt speed)")
        return ("the fitted motion never breaks away from stick, so static friction never "
                "decides a switch")
    return "the fitted response does not depend on it at all"


def _identifiability(model: LawModel, values: dict[str, float], se: dict[str, float],
                     cov: np.ndarray, dead: set[int], tr: Any,
                     ci: dict[str, tuple[float, float]]
                     ) -> tuple[dict[str, str], list[dict[str, Any]]]:
    """Flag each parameter whose 95 % interval is wider than its own magnitude (or its
    floor, :data:`SCALE_FLOOR`), and name the strongly correlated combinations that are
    determined instead."""
    flags: dict[str, str] = {}
    names = model.names
    for i in dead:
        flags[names[i]] = _dead_reason(names[i], tr)
        if names[i] == "xfs":
            ci["xfs"] = (values["xfk"], _reversal_bound(model, values, tr))
    weak = [i for i, n in enumerate(names) if i not in dead
            and Z95 * se[n] > max(abs(values[n]), SCALE_FLOOR.get(n, 0.1))]
    combos: list[dict[str, Any]] = []
    for i in weak:
        # the partner: the most correlated (|r| > 0.95) other parameter, one that is itself
        # undetermined first (lam with b1 where lam, b1, xfk and xfs all move together)
        partner, best, rank = None, 0.0, (-1, 0.0)
        for j in range(len(names)):
            if j == i or j in dead or names[j] in ("x0", "v0") and names[i] not in ("x0", "v0"):
                continue
            corr = cov[i, j] / math.sqrt(cov[i, i] * cov[j, j])
            key = (int(j in weak), abs(corr))
            if abs(corr) > 0.95 and key > rank:
                partner, best, rank = j, corr, key
        rel = se[names[i]] / max(abs(values[names[i]]), 1e-300)
        if partner is None:
            flags[names[i]] = (f"its 95 % interval (+-{Z95 * se[names[i]]:.3g}, "
                               f"{100 * rel:.3g} % of the value) is wider than the value: "
                               "the record hardly depends on it")
            continue
        combo = _combination(names, values, cov, i, partner)
        flags[names[i]] = (f"only a combination with {names[partner]} is determined "
                           f"({combo['name']} = {combo['value']:.4g} +- {combo['se']:.2g}; "
                           f"correlation {best:+.3f}); along the other direction the record "
                           "is nearly flat")
        if all(set(c["coefficients"]) != set(combo["coefficients"]) for c in combos):
            combos.append(combo)
    return flags, combos


#: 95 % quantile of chi-square with one degree of freedom: the likelihood-ratio interval's
#: threshold on -2 log L.
CHI2_95 = 3.841458820694124


def _widen_along_valley(model: LawModel, obj: _Objective, z: np.ndarray, cov: np.ndarray,
                        ci: dict[str, tuple[float, float]], n: int) -> None:
    """Where only a combination is determined, walk from the estimate along the flat
    direction (the covariance's leading eigenvector, in the estimated coordinates) both
    ways until ``-2 log L`` has risen by :data:`CHI2_95` or a bound stops the walk, and
    widen each interval to cover every point passed: a likelihood-ratio interval along
    the valley, which the linearisation at one end of it understates (a fit that stops at
    lam = 0 on a record that only fixes lam - b1 would otherwise exclude the truth)."""
    M = model.jac_map()
    Minv = np.linalg.inv(M)
    live = np.isfinite(np.diag(cov))
    c = np.where(np.outer(live, live), cov, 0.0)
    c_int = Minv @ c @ Minv.T
    w, vec = np.linalg.eigh(c_int)
    d = vec[:, -1] * math.sqrt(max(w[-1], 0.0))  # one standard deviation along the valley
    lo, hi = model.bounds()
    base = float(np.sum(obj.residuals(z) ** 2))
    seen = [z.copy()]
    for sign in (1.0, -1.0):
        step = 0.5
        for _ in range(24):
            trial = z + sign * step * d
            pinned = np.clip(trial, lo, hi)
            rss = float(np.sum(obj.residuals(pinned) ** 2))
            if n * math.log(rss / base) > CHI2_95:
                break
            seen.append(pinned)
            if np.any(pinned != trial):
                break  # a bound ends the valley
            step *= 1.5
    pts = np.array([model.to_internal(model.to_natural(p)) for p in seen]) @ M.T
    for i, name in enumerate(model.names):
        a, b = ci[name]
        ci[name] = (min(a, float(pts[:, i].min())), max(b, float(pts[:, i].max())))


def _combination(names: tuple[str, ...], values: dict[str, float], cov: np.ndarray,
                 i: int, j: int) -> dict[str, Any]:
    """``theta_i - a theta_j`` with ``a`` the slope of the flat direction: the combination
    the record determines when ``theta_i`` and ``theta_j`` move together."""
    a = math.copysign(math.sqrt(cov[i, i] / cov[j, j]), cov[i, j])
    var = cov[i, i] - 2.0 * a * cov[i, j] + a * a * cov[j, j]
    if abs(abs(a) - 1.0) < 0.05:
        a = math.copysign(1.0, a)
        name = f"{names[i]} {'-' if a > 0 else '+'} {names[j]}"
    else:
        name = f"{names[i]} {'-' if a > 0 else '+'} {abs(a):.3g} {names[j]}"
    return {"name": name, "coefficients": {names[i]: 1.0, names[j]: -a},
            "value": values[names[i]] - a * values[names[j]],
            "se": math.sqrt(max(var, 0.0))}


def _reversal_bound(model: LawModel, values: dict[str, float], tr: Any) -> float:
    """The smallest friction force a reversal through the belt speed needed: an upper
    bound on xfs (inf without reversals)."""
    forces = _reversal_forces(model, values, tr)
    return float(forces.min()) if forces.size else math.inf
