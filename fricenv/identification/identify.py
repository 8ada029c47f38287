"""The public ``identify`` and its result."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..checks import check_int, got
from ..params import OscillatorParams
from .fit import RESCUE_RATIO, LawFit, fit_law
from .model import DEFAULT_LAWS, LAW_UNKNOWNS, check_known, check_laws, check_record
from .threads import one_blas_thread

if TYPE_CHECKING:
    from matplotlib.figure import Figure


@dataclass
class IdentificationResult:
    """What :func:`identify` found.

    ``best`` is the law with the lowest BIC, ``params`` its fitted plant and ``ci`` its
    95 % intervals by name; ``fits`` holds every candidate's :class:`LawFit`;
    ``weights`` the BIC weights (``exp(-BIC/2)`` normalised), a rough posterior
    probability of each law among the candidates.

    ``tie`` names the laws this record cannot tell apart, ``best`` first: more than one
    where another candidate produces exactly the same motion as ``best``'s after a change
    of its parameters (:data:`ONE_SIDED_TWINS`), so that BIC prefers ``best`` only for
    its fewer parameters; ``(best,)`` otherwise. ``tie_reason`` says why.
    """

    best: str
    params: OscillatorParams
    ci: dict[str, tuple[float, float]]
    fits: dict[str, LawFit]
    weights: dict[str, float]
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray | None
    known: dict[str, float]
    seconds: float
    tie: tuple[str, ...] = ()
    tie_reason: str = ""

    @property
    def fit(self) -> LawFit:
        """The best law's fit."""
        return self.fits[self.best]

    @property
    def distinguishable(self) -> bool:
        """Whether the record singles out one law among the candidates (no :attr:`tie`)."""
        return len(self.tie) <= 1

    @property
    def converged(self) -> bool:
        """Whether every candidate's fit converged."""
        return all(f.converged for f in self.fits.values())

    def table(self) -> list[dict[str, Any]]:
        """The model-selection table: one row per law, lowest BIC first."""
        rows = []
        for law, f in sorted(self.fits.items(), key=lambda kv: kv[1].bic):
            rows.append({"law": law, "k": f.k, "loglik": f.loglik, "bic": f.bic,
                         "delta_bic": f.bic - self.fit.bic, "weight": self.weights[law],
                         "sigma_x": f.sigma["x"], "converged": f.converged,
                         "seconds": f.seconds})
        return rows

    def summary(self) -> str:
        """A plain-text report: the selection table, the best law's estimates with
        intervals, what the record cannot determine and why, and any fit that did not
        converge."""
        from .report import summary_text

        return summary_text(self)

    def plot(self) -> Figure:
        """Record against the best fit, residuals, interval bars and the model-selection
        table, on one figure."""
        from .report import result_figure

        return result_figure(self)


#: The paper's family nests: Coulomb is viscous at b1 = 0, viscous is the cubic law at
#: b3 = 0. (smaller, larger) pairs.
NESTED = (("coulomb", "viscous"), ("viscous", "stribeck"), ("coulomb", "stribeck"))


def _cross_nested(fits: dict[str, LawFit], t: np.ndarray, x: np.ndarray,
                  v: np.ndarray | None, known: dict[str, float], max_nfev: int) -> None:
    """Refit each of two nested laws from the other's estimate and keep the better fit.
    A larger law fits at least as well as a smaller one it contains, and a smaller one as
    well as the larger's estimate restricted to it, whenever that estimate sits near the
    smaller's family; a fit stuck on a kink of the cost (a tangential break-away) is moved
    off it so. Measured: a viscous record under a designed excitation whose viscous fit
    stopped 90 BIC units above the cubic fit with b3 = -0.0006."""
    for small, big in NESTED:
        if small not in fits or big not in fits:
            continue
        a, b = fits[small], fits[big]
        extra = {n: 0.0 for n in b.names if n not in a.names}
        pairs = ((big, a.estimates | extra, b), (small, {n: b.estimates[n] for n in a.names}, a))
        for law, warm, current in pairs:
            try:
                refit = fit_law(law, t, x, v, known, max_nfev=max_nfev, warm=warm)
            except ValueError:  # a restricted estimate outside the law's range
                continue
            if refit.loglik > current.loglik + 1e-9:
                refit.seconds += current.seconds
                fits[law] = refit


#: Pairs of laws (smaller, larger) whose fits are the same motion whenever it slips on one
#: side of the belt speed only: the viscous term ``b1 |v - V|`` is then linear in v, so
#: that b1 moves into lam and into the kinetic level (below the belt speed the record
#: determines ``lam - b1`` and ``xfk - b1 V`` only), and a Coulomb plant with those values
#: makes the identical record.
ONE_SIDED_TWINS = (("coulomb", "viscous"),)


def _tie(fits: dict[str, LawFit], best: str) -> tuple[tuple[str, ...], str]:
    """The laws the record cannot tell apart from ``best``, and why: a twin of
    :data:`ONE_SIDED_TWINS` where both fitted motions slip on one side of the belt speed
    only (the two laws are then the same model), or where the larger law's fit leaves
    its own parameter undetermined with an interval that holds the smaller law (a record
    whose only slip on the other side is too short to separate them, such as the start's
    first instants before the block first sticks)."""
    for small, big in ONE_SIDED_TWINS:
        if best not in (small, big) or small not in fits or big not in fits:
            continue
        other = big if best == small else small
        sides = {fits[small].slip_sides, fits[big].slip_sides}
        extra = LAW_UNKNOWNS[big][0]
        if len(sides) == 1 and len(next(iter(sides))) <= 1:
            phrases: dict[tuple[int, ...], str] = {(-1,): "slips only below",
                                                   (1,): "slips only above"}
            why = (f"the fitted motion {phrases.get(next(iter(sides)), 'never slips off')} "
                   f"the belt speed, where the viscous term is linear in v, so that {extra} "
                   "only shifts lam and xfk (the record determines two combinations of the "
                   "three)")
        elif (extra in fits[big].undetermined
              and fits[big].ci[extra][0] <= 0.0 <= fits[big].ci[extra][1]):
            lo, hi = fits[big].ci[extra]
            why = (f"the {big} fit cannot determine {extra}, whose 95 % interval "
                   f"[{lo:.3g}, {hi:.3g}] holds {extra} = 0, the {small} law")
        else:
            continue
        return (best, other), (
            f"{small} and {big} are indistinguishable on this record: {why}; BIC's "
            f"preference for {best} is no evidence against {other}")
    return (best,), ""


def identify(t: Sequence[float] | np.ndarray, x: Sequence[float] | np.ndarray, *,
             known: Mapping[str, float], laws: Sequence[str] = DEFAULT_LAWS,
             v: Sequence[float] | np.ndarray | None = None, n_starts: int = 3,
             max_nfev: int = 100, seed: int = 0) -> IdentificationResult:
    """Which friction law, with which parameters, produced the record ``(t, x)``.

    ``t`` and ``x`` are the measured record (uniform in time or not), ``v`` the velocity if
    it was measured too. ``known`` holds the rig's settings: ``eta``, ``nu``, ``u0`` (or
    ``u1`` and ``u2``) and ``V``; the forcing is ``u1 cos(eta t) + u2 cos(nu eta t)`` on the
    record's clock. Everything else is estimated: the friction law's parameters, ``lam``,
    the initial state ``(x0, v0)`` at ``t[0]`` and the noise level of each channel.

    Each law of ``laws`` (``coulomb``, ``viscous``, ``stribeck``, ``exponential``) is
    fitted by output-error least squares on the exact simulator, with the exact Jacobian,
    from ``n_starts`` starts (the law's preset values, the Coulomb fit's levels, then
    seeded draws around the preset); ``max_nfev`` bounds each start's evaluations. The
    laws are ranked by BIC. A record the simulator cannot follow, or a fit that stops on
    ``max_nfev``, is reported in ``fits[law].message`` and ``converged``.

    Refused, naming the value: NaN or inf in the record, times that do not increase, a
    record shorter than one forcing period (``2 pi / eta``), ``known`` missing a setting
    or naming one it cannot hold.
    """
    known_ = check_known(known)
    laws_ = check_laws(laws)
    ta, xa, va = check_record(t, x, v, known_)
    n_starts = check_int("n_starts", n_starts, 1)
    max_nfev = check_int("max_nfev", max_nfev, 1)
    if not isinstance(seed, int | np.integer):
        raise TypeError(f"seed must be an int, {got(seed)}")
    import time

    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    fits: dict[str, LawFit] = {}
    ordered = sorted(laws_, key=lambda law: law != "coulomb")  # its fit seeds the others
    with one_blas_thread():  # (small SVDs at every iteration: see .threads)
        for law in ordered:
            seeds = [fits["coulomb"].estimates] if "coulomb" in fits else []
            explained = any(f.residual_ratio <= RESCUE_RATIO for f in fits.values())
            fits[law] = fit_law(law, ta, xa, va, known_, n_starts=n_starts,
                                max_nfev=max_nfev, rng=rng, seeds=seeds, explained=explained)
        _cross_nested(fits, ta, xa, va, known_, max_nfev)
    fits = {law: fits[law] for law in laws_}
    best = min(fits, key=lambda law: fits[law].bic)
    b = min(f.bic for f in fits.values())
    w = {law: math.exp(-0.5 * (f.bic - b)) for law, f in fits.items()}
    total = sum(w.values())
    tie, why = _tie(fits, best)
    return IdentificationResult(
        best=best, params=fits[best].params, ci=dict(fits[best].ci), fits=fits,
        weights={law: w[law] / total for law in fits}, t=ta, x=xa, v=va, known=known_,
        seconds=time.perf_counter() - t0, tie=tie, tie_reason=why)
