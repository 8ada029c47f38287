"""Text, figures and the Markdown report of an identification and of a design."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

# (the results are typed Any here: report is imported by the modules that define them)
Design = Any
IdentificationResult = Any


def _fmt_ci(lo: float, hi: float) -> str:
    return f"[{lo:.4g}, {hi:.4g}]"


def _tie_note(res: IdentificationResult) -> str:
    """`` (indistinguishable from ...)`` where the record cannot tell ``best`` apart."""
    others = [law for law in res.tie if law != res.best]
    return f" (indistinguishable from {', '.join(others)})" if others else ""


def summary_text(res: IdentificationResult) -> str:
    """The selection table, the best law's estimates, flags and convergence notes."""
    lines = [f"best law: {res.best}{_tie_note(res)}  (BIC weight {res.weights[res.best]:.3f}; "
             f"{res.t.size} samples, {res.seconds:.2f} s)", "",
             f"{'law':<12}{'k':>3}{'logL':>12}{'BIC':>12}{'dBIC':>9}{'weight':>9}  converged"]
    if len(res.tie) > 1:
        lines[1:1] = [f"tie: {res.tie_reason}"]
    for row in res.table():
        lines.append(f"{row['law']:<12}{row['k']:>3}{row['loglik']:>12.2f}{row['bic']:>12.2f}"
                     f"{row['delta_bic']:>9.2f}{row['weight']:>9.3f}  {row['converged']}")
    fit = res.fit
    lines += ["", f"{res.best}: estimate, standard error, 95 % interval",
              *(f"  {n:<5}{fit.estimates[n]:>11.5g} {fit.se[n]:>11.3g}  "
                f"{_fmt_ci(*fit.ci[n])}" + ("  (undetermined)" if n in fit.undetermined
                                           else "") for n in fit.names),
              "  noise sigma: " + ", ".join(f"{k} {s:.4g}" for k, s in fit.sigma.items())
              + f" (the record's own noise level in x: {fit.noise:.4g}, residual ratio "
              f"{fit.residual_ratio:.3f})"]
    if fit.undetermined:
        lines += ["", "not determined by this record:"]
        lines += [f"  {n}: {why}" for n, why in fit.undetermined.items()]
    for c in fit.combinations:
        lines.append(f"  determined instead: {c['name']} = {c['value']:.5g} +- {c['se']:.3g}")
    bad = [f for f in res.fits.values() if not f.converged]
    if bad:
        lines += ["", *(f"{f.law}: {f.message}" for f in bad)]
    return "\n".join(lines)


def result_figure(res: IdentificationResult) -> Figure:
    """Record against the best fit, residuals, relative interval bars, and the table."""
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(10, 7.5), layout="constrained")
    grid = fig.add_gridspec(3, 2, height_ratios=[1.2, 0.7, 1.0])
    ax = fig.add_subplot(grid[0, :])
    fit = res.fit
    ax.plot(res.t, res.x, ".", ms=2, color="0.5", label="record")
    ax.plot(res.t, fit.fitted_x, lw=1.2, color="C0", label=f"fit ({res.best})")
    stick = np.zeros(res.t.size, bool)
    for ev0, ev1 in _stick_intervals(fit.events, float(res.t[-1])):
        stick |= (res.t >= ev0) & (res.t <= ev1)
    ax.fill_between(res.t, 0, 1, where=stick, transform=ax.get_xaxis_transform(),
                    color="C1", alpha=0.12, lw=0, label="fitted stick")
    ax.set_ylabel("x")
    ax.legend(loc="upper right", fontsize=8, ncol=3)
    ax2 = fig.add_subplot(grid[1, :], sharex=ax)
    ax2.plot(res.t, fit.residuals[:, 0], lw=0.6, color="C3")
    ax2.set_ylabel("residual x")
    ax2.set_xlabel("t")
    ax3 = fig.add_subplot(grid[2, 0])
    names = [n for n in fit.names if n not in ("x0", "v0")]
    est = np.array([fit.estimates[n] for n in names])
    half = np.array([0.5 * (fit.ci[n][1] - fit.ci[n][0]) for n in names])
    rel = np.where(est != 0, half / np.abs(np.where(est != 0, est, 1)), np.inf)
    shown = np.minimum(rel, 10.0)
    colors = ["C3" if n in fit.undetermined else "C0" for n in names]
    ax3.barh(names, 100 * shown, color=colors)
    ax3.set_xscale("log")
    ax3.set_xlabel("95 % half-width, % of value (red: undetermined)")
    ax4 = fig.add_subplot(grid[2, 1])
    ax4.axis("off")
    rows = [[r["law"], f"{r['bic']:.1f}", f"{r['delta_bic']:.1f}", f"{r['weight']:.2f}",
             "yes" if r["converged"] else "NO"] for r in res.table()]
    table = ax4.table(cellText=rows, colLabels=["law", "BIC", "dBIC", "weight", "conv."],
                      loc="center")
    table.scale(1, 1.3)
    fig.suptitle(f"identified: {res.best}{_tie_note(res)}", fontsize=11)
    return fig


def _stick_intervals(events: np.ndarray, t_end: float) -> list[tuple[float, float]]:
    out, t_in = [], None
    for ev in events:
        if ev["kind"] == 1:
            t_in = float(ev["t"])
        elif ev["kind"] == 2 and t_in is not None:
            out.append((t_in, float(ev["t"])))
            t_in = None
    if t_in is not None:
        out.append((t_in, t_end))
    return out


def write_report(res: IdentificationResult, folder: str | Path, *, source: str = "record"
                 ) -> Path:
    """``report.md`` and ``identification.png`` in ``folder`` (made if missing); the
    report's path."""
    from .. import plotting

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    plotting.save(res.plot(), folder / "identification.png")
    fit = res.fit
    lines = [f"# Friction identification of `{source}`", "",
             "Settings: " + ", ".join(f"{k} = {v:g}" for k, v in res.known.items()
                                       if not (k == "u0" and v == 0.0)), "",
             f"Best law: **{res.best}**{_tie_note(res)} (BIC weight "
             f"{res.weights[res.best]:.3f}).", *(["", res.tie_reason + "."]
                                                 if len(res.tie) > 1 else []), "",
             "| law | k | log-likelihood | BIC | ΔBIC | weight | converged |",
             "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['law']} | {r['k']} | {r['loglik']:.2f} | {r['bic']:.2f} | "
              f"{r['delta_bic']:.2f} | {r['weight']:.3f} | {r['converged']} |"
              for r in res.table()]
    lines += ["", f"## {res.best}: estimates", "",
              "| parameter | estimate | standard error (CRLB) | 95 % interval | note |",
              "|---|---|---|---|---|"]
    lines += [f"| {n} | {fit.estimates[n]:.5g} | {fit.se[n]:.3g} | {_fmt_ci(*fit.ci[n])} | "
              f"{fit.undetermined.get(n, '')} |" for n in fit.names]
    for c in fit.combinations:
        lines += ["", f"Determined instead: `{c['name']}` = {c['value']:.5g} ± {c['se']:.3g}."]
    lines += ["", "Noise level: " + ", ".join(f"{k} {s:.4g}" for k, s in fit.sigma.items()),
              "", "![record, fit, residuals, intervals](identification.png)", ""]
    bad = [f for f in res.fits.values() if not f.converged]
    lines += [f"- {f.law}: {f.message}" for f in bad]
    path = folder / "report.md"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def design_figure(design: Design, map_size: int = 16) -> Figure:
    """The prior's regime map around the design, the designed response, the bounds."""
    import matplotlib.pyplot as plt

    from .. import plotting
    from ..sweep import regime_map
    from .model import DEFAULT_EXCITATION, start_state

    p = design.plant
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), layout="constrained")
    u_hi = max(design.bounds.get("u0", (0.0, 2 * p.u0 + 1))[1], p.u0, 1.6)
    nu_hi = max(design.bounds.get("nu", (0.0, 2 * p.nu + 0.5))[1], p.nu, 0.4)
    base = design.prior.replace(eta=p.eta, u1=None, u2=None)
    rmap = regime_map(base, np.linspace(0.05, u_hi, map_size),
                      np.linspace(0.02, nu_hi, map_size), progress=False)
    plotting.draw_regime_map(axes[0], rmap)
    axes[0].plot([p.nu], [p.u0], "*", ms=16, mec="k", mfc="w", label="design")
    axes[0].plot([DEFAULT_EXCITATION["nu"]], [DEFAULT_EXCITATION["u0"]], "X", ms=11,
                 mec="k", mfc="0.6", label="default")
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title(f"prior's regimes at eta = {p.eta:.3g}", fontsize=10)
    from ..simulate import simulate

    t = np.arange(0.0, design.duration + 0.5 * design.dt, design.dt)
    tr = simulate(p, state=start_state(p, 0.0, *design.start), t_eval=t)
    plotting.draw_velocity(axes[1], tr.t, tr.v, tr.mode, p.V)
    axes[1].set_title("designed response", fontsize=10)
    names = list(design.wrt)
    axes[2].barh(names, [100 * design.crlb_relative[n] for n in names], color="C0")
    axes[2].set_xscale("log")
    axes[2].set_xlabel(f"CRLB, % of the prior's value ({design.snr_db:g} dB)")
    fig.suptitle(", ".join(f"{k} = {v:.4g}" for k, v in design.settings.items())
                 + f"  ({design.criterion}-optimal)", fontsize=11)
    return fig


def design_text(design: Design) -> str:
    """The design's settings, bounds per parameter and what the response does."""
    lines = [f"{design.criterion}-optimal excitation for a {design.duration:g}-long x "
             f"record at {design.snr_db:g} dB:"]
    lines += [f"  {k} = {v:.5g}" for k, v in design.settings.items()]
    lines += ["Cramér-Rao bound (standard deviation, % of the prior's value):"]
    lines += [f"  {n:<5}{design.crlb[n]:.4g}  ({100 * design.crlb_relative[n]:.3g} %)"
              for n in design.wrt]
    r: dict[str, Any] = design.regime
    lines.append(f"response: stick fraction {r['stick_fraction']:.3f}, {r['n_stick']} stick "
                 f"phases, {r['n_reversals']} reversals, slips above the belt: "
                 f"{r['slips_above_belt']}")
    return "\n".join(lines)


def _finite(x: float) -> str:
    return f"{x:.4g}" if math.isfinite(x) else "inf"
