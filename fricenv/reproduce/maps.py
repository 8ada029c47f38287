"""Figs. 8-10: the regime maps, and the paper's observations on them."""

from __future__ import annotations

import logging
import math
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..params import OscillatorParams
from ..regimes import Regime
from ..sweep import (
    RegimeMap,
    SweepSettings,
    regime_map,
)
from .common import (
    MAP_FIGURES,
    Band,
    Report,
    Resolution,
    _frac,
    _map_path,
    _mean,
    _median,
    _straightness,
    _verdict,
    band,
    contact_category,
    eta_name,
    map_grid,
)


def figs8_10(rep: Report, out: Path, docs: Path | None, res: Resolution,
             settings: SweepSettings, n_threads: int | None, progress: bool,
             timings: dict[str, float]) -> None:
    """Compute (or resume) the maps, draw Figs. 8-10 into ``out`` (and ``docs``) and add
    the paper's observations on them to ``rep``."""
    from .. import plotting

    maps: dict[int, list[RegimeMap]] = {}
    n_panels = sum(len(ps) for _, ps in MAP_FIGURES.values())
    for fig, (law, panels_) in MAP_FIGURES.items():
        maps[fig] = []
        for eta, u_range in panels_:
            logging.getLogger("fricenv").info(
                f"  panel {sum(map(len, maps.values())) + 1}/{n_panels}: Fig. {fig}, {law}, "
                f"η = {eta_name(eta)}, {res.n_u0} x {res.n_nu} cells")
            u0, nu = map_grid(u_range, res)
            p = OscillatorParams.preset(law, eta=eta)
            path = _map_path(out, fig, law, eta, res)
            try:
                m = regime_map(p, u0, nu, settings=settings, path=path,
                               n_threads=n_threads, progress=progress,
                               meta={"figure": fig})
            except ValueError:  # a cache from other settings or code: start over
                print(f"note: {path} was made with other settings; recomputing",
                      file=sys.stderr)
                m = regime_map(p, u0, nu, settings=settings, path=path, resume=False,
                               n_threads=n_threads, progress=progress,
                               meta={"figure": fig})
            timings[f"Fig. {fig} η={eta_name(eta)}"] = m.elapsed
            maps[fig].append(m)
        titles = [f"({'abcd'[k]}) η = {eta_name(e)}" for k, (e, _) in enumerate(panels_)]
        fig_obj = plotting.regime_maps_figure(
            maps[fig], titles, suptitle=f"Fig. {fig}: {plotting.LAW_TITLES[law]} law, "
            f"λ = 1/2, V = 1, from rest")
        name = f"fig{fig}_regime_maps.png"
        plotting.save(fig_obj, out / name)
        if docs is not None:
            docs.mkdir(parents=True, exist_ok=True)
            if not ((docs / name).exists() and (docs / name).samefile(out / name)):
                shutil.copy(out / name, docs / name)  # (docs may be out itself)
    _map_observations(rep, maps)



@dataclass
class _Maps:
    """The maps of Figs. 8-10 and what every observation on them reads."""

    maps: dict[int, list[RegimeMap]]
    bands: dict[int, list[Band]]
    etas: dict[int, list[float]]
    non_int: dict[int, list[np.ndarray]]  # each panel's non-integer nu columns

    @classmethod
    def of(cls, maps: dict[int, list[RegimeMap]]) -> _Maps:
        bands = {fig: [band(m) for m in ms] for fig, ms in maps.items()}
        return cls(maps, bands, {fig: [m.params.eta for m in ms] for fig, ms in maps.items()},
                   {fig: [~np.isclose(b.nu, np.round(b.nu)) for b in bs]
                    for fig, bs in bands.items()})

    def name(self, fig: int, k: int) -> str:
        return f"{fig}{'abcd'[k]} (η={eta_name(self.etas[fig][k])})"


def _map_observations(rep: Report, maps: dict[int, list[RegimeMap]]) -> None:
    """The paper's observations on its regime maps, checked on ours: a table of checks,
    one function each (``MAP_CHECKS``)."""
    rep.add("## Figs. 8–10: regime maps", "")
    for fig in maps:
        rep.add(f"![Fig. {fig}](fig{fig}_regime_maps.png)", "")
    c = _Maps.of(maps)
    for check in MAP_CHECKS:
        check(rep, c)
    rep.flush_table()


def _regime_shares(rep: Report, c: _Maps) -> None:
    """Share of the cells of each panel in each regime."""
    maps, name = c.maps, c.name
    rep.add("Share of cells per regime (%):", "",
            "| panel | " + " | ".join(r.name for r in Regime) + " |",
            "|---|" + "---|" * len(Regime))
    for fig, ms in maps.items():
        for k, m in enumerate(ms):
            counts = m.counts()
            rep.add(f"| {name(fig, k)} | " + " | ".join(
                f"{100 * counts[r.name] / m.labels.size:.1f}" for r in Regime) + " |")
    rep.add("")



def _two_boundaries(rep: Report, c: _Maps) -> None:
    """M1: no contact, then stick phases, then reversals only, as u0 grows."""
    bands, non_int = c.bands, c.non_int
    mono = {fig: [_mean(b.monotone[s]) for b, s in zip(bs, non_int[fig], strict=True)]
            for fig, bs in bands.items()}
    reach = [_mean(b.reaches_wm2[s]) for fig, bs in bands.items()
             for b, s in zip(bs, non_int[fig], strict=True)]
    first = [float(np.all(np.isfinite(b.onset))) for bs in bands.values() for b in bs]
    worst = min(min(v) for v in mono.values())
    rep.obs("Figs. 8–10", "two boundary curves: WM below the first, SSM between, WM again "
            "beyond the second (as u0 grows)",
            "every ν column has a first boundary (stick onset) in "
            f"{int(sum(first))} of {len(first)} panels; share of the non-integer ν columns "
            "whose sequence along u0 is exactly no contact → stick phases → reversals only: "
            + "; ".join(f"Fig. {fig}: " + ", ".join(f"{100 * v:.0f} %" for v in vs)
                        for fig, vs in mono.items())
            + f"; {min(reach) * 100:.0f}–{max(reach) * 100:.0f} % of the columns end in "
            "the reversal-only regime inside the plotted range. Deviations are isolated "
            "stick islands beyond the second boundary (mostly Stribeck, η ≥ 3/5) and "
            "columns next to integer ν, where the slow drift of the tones' relative phase "
            "keeps stick phases alive up to very large u0.",
            _verdict(worst > 0.9, partly=True, inputs=[v for vs in mono.values() for v in vs]))



def _split_at_nu1(rep: Report, c: _Maps) -> None:
    """M2: SSM1 ends at nu = 1 and SSM2 begins above it."""
    bands = c.bands
    jumps = []
    for bs in bands.values():
        for b in bs:
            lo = b.at(0.98 if b.nu.size >= 100 else 0.9)[0]
            hi = b.at(1.02 if b.nu.size >= 100 else 1.1)[0]
            if math.isfinite(lo) and math.isfinite(hi):
                jumps.append(hi / lo)
    rep.obs("Fig. 8b", "SSM1 ends at ν = 1 and SSM2 begins above it",
            "true by definition of the labels; physically the stick band is continuous "
            "across ν = 1: the stick onset on either side of ν = 1 differs by a factor "
            f"{min(jumps):.2f}–{max(jumps):.2f} over the 12 panels" if jumps else "–",
            "agree (by definition)")



def _small_eta_onset(rep: Report, c: _Maps) -> None:
    """M3: for small eta stick starts at large u0, earlier as nu grows."""
    bands, etas = c.bands, c.etas
    if 8 not in bands:
        return
    med_on = [_median(b.onset) for b in bands[8]]
    rep.obs("Fig. 8a/8b", "for small η (1/9, 1/5) stick-slip needs large u0 (first "
            "boundary far from the ν axis) and it starts at smaller u0 as ν grows",
            "median stick onset u0: " + ", ".join(
                f"η={eta_name(e)}: {v:.3g}" for e, v in zip(etas[8], med_on, strict=True))
            + "; onset at ν = 0.5 / 2.5 / 3.9: " + "; ".join(
                f"η={eta_name(e)}: {b.at(0.5)[0]:.3g} / {b.at(2.5)[0]:.3g} / "
                f"{b.at(3.9)[0]:.3g}" for e, b in zip(etas[8], bands[8], strict=True)),
            _verdict(med_on[0] > med_on[2] and med_on[1] > med_on[2]
                     and bands[8][0].at(3.9)[0] < bands[8][0].at(0.5)[0],
                     inputs=med_on[:3]))



def _ssm2_gap(rep: Report, c: _Maps) -> None:
    """M4: for 1 < nu < 3 there is almost no SSM2 at eta = 1/9, 1/5."""
    maps, bands, etas, non_int = c.maps, c.bands, c.etas, c.non_int
    if 8 not in bands:
        return
    txt, ok, shares = [], True, []
    for k in (0, 1):
        m = maps[8][k]
        stick = contact_category(m) == 1
        sel13 = (m.nu > 1) & (m.nu < 3) & non_int[8][k]
        sel34 = (m.nu > 3) & non_int[8][k]
        f13, f34 = _frac(stick, sel13[None, :]), _frac(stick, sel34[None, :])
        on13 = _median(bands[8][k].onset[sel13])
        end13 = _median(bands[8][k].end[sel13])
        txt.append(f"η={eta_name(etas[8][k])}: {100 * f13:.0f} % of the cells with "
                   f"1 < ν < 3 have stick phases ({100 * f34:.0f} % for ν > 3); median "
                   f"band u0 ∈ [{on13:.3g}, {end13:.3g}]")
        ok &= f13 < 0.1
        shares.append(f13)
    rep.obs("Fig. 8a/8b", "for 1 < ν < 3 there is almost no SSM2 at η = 1/9 and none "
            "at η = 1/5; some u0 near ν = 1 fall outside the diagram",
            "; ".join(txt) + ". Near ν = 1 the band's far edge leaves the plotted "
            "range (beats).", _verdict(ok, inputs=shares))



def _band_growth(rep: Report, c: _Maps) -> None:
    """M5/M6: the band for nu > 3 and its growth with nu when eta < 1."""
    bands, etas = c.bands, c.etas
    if 8 not in bands:
        return
    txt, trend, widths = [], [], []
    for k in (0, 1):
        b = bands[8][k]
        lin = b.end - b.onset
        sel_lo = (b.nu > 0.2) & (b.nu < 0.8)
        sel_hi = b.nu > 3
        txt.append(f"η={eta_name(etas[8][k])}: band width in u0 (end − onset) median "
                   f"{_median(lin[sel_lo]):.3g} for 0.2<ν<0.8 vs "
                   f"{_median(lin[sel_hi]):.3g} for ν>3; in decades "
                   f"{_median(b.decades()[sel_lo]):.2f} vs "
                   f"{_median(b.decades()[sel_hi]):.2f}")
        widths += [_median(lin[sel_hi]), _median(lin[sel_lo])]
        trend.append(widths[-2] > widths[-1])
    rep.obs("Fig. 8", "for ω1 < ω0 the stick-slip band widens as ν increases, and for "
            "ν > 3 it is wide at small u0",
            "; ".join(txt) + ". The band moves to smaller u0 as ν grows, but it gets "
            "narrower, both in u0 and in decades.", _verdict(all(trend), inputs=widths))



def _large_eta(rep: Report, c: _Maps) -> None:
    """M8: eta > 1 shrinks the band."""
    bands, etas = c.bands, c.etas
    if 8 not in bands:
        return
    dec = [_median(b.decades()) for b in bands[8]]
    on8 = [_median(b.onset) for b in bands[8]]
    rep.obs("Fig. 8c/8d", "for η > 1 the curves lie at the right and stick is "
            "suppressed; larger η shrinks the stick-slip band",
            "median band width in decades of u0: " + ", ".join(
                f"η={eta_name(e)}: {d:.2f}" for e, d in zip(etas[8], dec, strict=True))
            + "; median onset u0: " + ", ".join(
                f"η={eta_name(e)}: {_median(b.onset):.3g}"
                for e, b in zip(etas[8], bands[8], strict=True))
            + ". The band is narrower for η > 1 but it is not suppressed, and it starts at "
            "smaller u0 than for η < 1 (its first boundary lies further left).",
            _verdict(max(dec[2:]) < min(dec[:2]) and min(on8[2:]) > max(on8[:2]),
                     partly=max(dec[2:]) < min(dec[:2]), inputs=dec + on8))



def _integer_nu(rep: Report, c: _Maps) -> None:
    """M7: integer nu rows lock to a periodic response."""
    maps, name = c.maps, c.name
    per_txt, ok, shares = [], True, []
    for fig, ms in maps.items():
        for k, m in enumerate(ms):
            ints = np.isclose(m.nu, np.round(m.nu))
            lab = m.labels[:, ints]
            per = np.isin(lab, [Regime.PERIODIC_OSCILLATION, Regime.PERIODIC_STICK_SLIP])
            stick = contact_category(m)[:, ints] == 1
            pss = (lab == Regime.PERIODIC_STICK_SLIP)
            shares.append(_mean(per))
            per_txt.append(f"{name(fig, k)}: {100 * shares[-1]:.0f} % periodic"
                           f" ({100 * _frac(pss, stick):.0f} % of the stick cells)")
            ok &= shares[-1] > 0.5
    rep.obs("Figs. 8–10", "at integer ν: periodic oscillation on both sides of the "
            "stick-slip band, periodic stick-slip inside it",
            "share of integer-ν cells with a locked response: " + "; ".join(per_txt),
            _verdict(ok, partly=True, inputs=shares))



def _figs9_10(rep: Report, c: _Maps) -> None:
    """Figs. 9 and 10: the viscous and Stribeck maps' own observations."""
    maps, bands, etas = c.maps, c.bands, c.etas
    for fig in (9, 10):
        if fig not in maps:
            continue
        low = [_frac(contact_category(m) == 1, (m.nu <= 1)[None, :]) for m in maps[fig]]
        mid = [_frac(contact_category(m) == 1, ((m.nu >= 2) & (m.nu <= 3))[None, :])
               for m in maps[fig]]
        rest = [_frac(contact_category(m) == 1, ((m.nu < 2) | (m.nu > 3))[None, :])
                for m in maps[fig]]
        if fig == 9:
            rep.obs("Fig. 9", "Coulomb + viscosity: SSM1 (ν ≤ 1) mostly nil or outside the "
                    "plane; for ν in [2, 3] the band nearly vanishes",
                    "share of cells with stick for ν ≤ 1: " + ", ".join(
                        f"η={eta_name(e)}: {100 * v:.0f} %"
                        for e, v in zip(etas[fig], low, strict=True))
                    + "; for 2 ≤ ν ≤ 3 vs the rest: " + ", ".join(
                        f"{100 * a:.0f} % vs {100 * b:.0f} %"
                        for a, b in zip(mid, rest, strict=True)),
                    _verdict(max(low) < 0.05 and all(a < 0.5 * b for a, b in zip(mid, rest,
                                                                                   strict=True)),
                             inputs=low + mid + rest))
        straight_k = 1 if fig == 9 else 2
        b = bands[fig][straight_k]
        st_on = _straightness(b.nu, b.onset)
        st_end = _straightness(b.nu, b.end)
        others = [_straightness(bb.nu, bb.onset) for kk, bb in enumerate(bands[fig])
                  if kk != straight_k]
        rep.obs(f"Fig. {fig}{'abcd'[straight_k]}",
                f"η = {eta_name(etas[fig][straight_k])}: the limit curves are rather straight",
                "RMS deviation of the boundary u0(ν) from a straight line, relative to its "
                f"median: {st_on:.2f} (stick onset), {st_end:.2f} (stick end); other panels' "
                "onset: " + ", ".join(f"{v:.2f}" for v in others)
                + f". The onset goes from {b.at(0.1)[0]:.3g} at ν = 0.1 to "
                f"{b.at(3.9)[0]:.3g} at ν = 3.9",
                _verdict(st_on < 0.1, partly=st_on <= min(others), inputs=[st_on, *others]))
        dec = [_median(bb.decades()) for bb in bands[fig]]
        ons = [_median(bb.onset) for bb in bands[fig]]
        rep.obs(f"Fig. {fig}d", "η = 7/3: the stick-slip band is weak / partly disappears "
                "and needs large u0",
                "median band width in decades of u0 (from the stick onset to the last stick): "
                + ", ".join(f"η={eta_name(e)}: {d:.2f}"
                            for e, d in zip(etas[fig], dec, strict=True))
                + "; median onset u0: " + ", ".join(
                    f"η={eta_name(e)}: {o:.3g}" for e, o in zip(etas[fig], ons, strict=True)),
                _verdict(dec[3] < min(dec[:3]) and ons[3] > max(ons[:3]),
                         partly=dec[3] < max(dec[:3]) or ons[3] > min(ons[:3]),
                         inputs=dec + ons))


def _stribeck_vs_viscous(rep: Report, c: _Maps) -> None:
    """Fig. 10 against Figs. 8 and 9: the Stribeck maps are not very different."""
    bands, etas = c.bands, c.etas
    if not (10 in bands and 8 in bands and 9 in bands):
        return
    rows = []
    for k_strib, k_coul, k_visc in ((0, 0, 0), (3, 3, 3)):
        b10, b8, b9 = bands[10][k_strib], bands[8][k_coul], bands[9][k_visc]
        rows.append(f"η={eta_name(etas[10][k_strib])}: median onset "
                    f"{_median(b8.onset):.3g} / {_median(b9.onset):.3g} / "
                    f"{_median(b10.onset):.3g}, median end "
                    f"{_median(b8.end):.3g} / {_median(b9.end):.3g} / "
                    f"{_median(b10.end):.3g} (Coulomb / viscous / Stribeck)")
    ratios = [(_median(bands[10][k].onset) / _median(bands[9][k].onset),
               _median(bands[10][k].end) / _median(bands[9][k].end)) for k in (0, 3)]
    on_ok = all(abs(on - 1) < 0.1 for on, _ in ratios)
    end_ok = all(end < 1.5 for _, end in ratios)
    rep.obs("Fig. 10", "Stribeck maps are not very different from Fig. 9", "; ".join(rows)
            + ". The first boundary hardly moves; the cubic term pushes the second one "
            "to much larger u0 and leaves stick islands beyond it.",
            _verdict(on_ok and end_ok, partly=on_ok, inputs=[v for r in ratios for v in r]))


#: The observations checked on the maps, in the report's order.
MAP_CHECKS = (_regime_shares, _two_boundaries, _split_at_nu1, _small_eta_onset, _ssm2_gap,
              _band_growth, _large_eta, _integer_nu, _figs9_10, _stribeck_vs_viscous)
