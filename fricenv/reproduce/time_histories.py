"""Figs. 4-7: time histories of the paper's cases, and its labels for them."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..layout import (
    ST_DURATION,
    ST_N_REVERSAL,
    ST_N_STICK,
    ST_STICK_TIME,
    ST_V_MAX,
    ST_V_MIN,
)
from ..params import OscillatorParams
from ..regimes import Regime
from ..sweep import (
    SweepSettings,
    cell_statistics,
    modulation_period,
)
from .common import TIME_HISTORIES, Report, _verdict


def figs4_7(rep: Report, out: Path, settings: SweepSettings, n_threads: int | None,
            timings: dict[str, float]) -> None:
    """Draw Figs. 4-7 into ``out`` and add the paper's label of each case to ``rep``."""
    from .. import plotting
    from ..simulate import simulate

    t0 = time.perf_counter()
    ps = [OscillatorParams.preset("coulomb", **kw) for _, _, kw, _ in TIME_HISTORIES]
    labels, stats, period, status = cell_statistics(ps, settings, n_threads)
    runs: dict[int, list[dict]] = {}
    rep.add("## Figs. 4–7: time histories", "")
    for (fig, panel, _kw, paper_label), p, lab, st, per in zip(
            TIME_HISTORIES, ps, labels, stats, period, strict=True):
        t_mod = float(modulation_period(p.eta, np.array([p.nu]), 100.0)[0])
        t_end = max(300.0, 2.0 * t_mod)
        tr = simulate(p, t_end, dt_out=0.05)
        ours = Regime(int(lab))
        title = (f"({panel}) " if panel else "") + (
            f"ν = {p.nu:g}, u0 = {p.u0:g}, η = {p.eta:.3g}: {ours.name}")
        runs.setdefault(fig, []).append(dict(t=tr.t, x=tr.x, v=tr.v, mode=tr.mode,
                                             V=p.V, title=title))
        sf = st[ST_STICK_TIME] / st[ST_DURATION]
        facts = (f"{ours.name}: stick fraction {sf:.3f}, {int(st[ST_N_STICK])} stick "
                 f"phases and {int(st[ST_N_REVERSAL])} reversals in a window of "
                 f"{st[ST_DURATION]:.0f}; v in [{st[ST_V_MIN]:.3f}, {st[ST_V_MAX]:.3f}]"
                 + (f"; period {int(per)}·2π/η" if per else ""))
        if fig == 4:
            verdict = ("agree" if ours.name == paper_label[:3] else
                       "partly (no stick, as stated; name differs by our contact-based "
                       "definition)" if not ours.has_stick else "differ")
        elif fig == 5:
            verdict = _verdict(ours.has_stick and ours == Regime.SSM1)
        elif fig == 6:
            verdict = ("caption: agree (stick phases, ν > 1); text's 'no stick': differ"
                       if ours == Regime.SSM2 else
                       "caption: differ; text: agree" if not ours.has_stick else "differ")
        else:
            verdict = ("caption: agree; text: differ" if ours ==
                       Regime.PERIODIC_OSCILLATION else
                       "caption: differ; text: agree" if ours ==
                       Regime.PERIODIC_STICK_SLIP else "differ")
        rep.obs(f"Fig. {fig}{panel}: ν={p.nu:g}, u0={p.u0:g}, η={p.eta:.3g}",
                paper_label, facts, verdict)
    for fig, rr in runs.items():
        plotting.save(plotting.time_history_figure(
            rr, suptitle=f"Fig. {fig}: Coulomb law, λ = 1/2, V = 1 (from rest)"),
            out / f"fig{fig}_time_history.png")
    rep.flush_table()
    rep.add(" ".join(f"![Fig. {f}](fig{f}_time_history.png)" for f in runs), "")
    timings["Figs. 4-7"] = time.perf_counter() - t0

