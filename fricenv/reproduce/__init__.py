"""Reproduce the paper's Figs. 2-10 and compare its observations with our simulations.

``fricenv-reproduce [--quick] [--out DIR] [--docs DIR]`` (or ``python
scripts/reproduce_paper.py``) writes the figures and ``report.md`` into ``--out``. Regime
maps are cached as resumable ``.npz`` files under ``OUT/maps``: an interrupted run picks up
where it stopped. Choices the paper leaves open (axis ranges, initial state, transient) are
the module constants below and the defaults of :class:`fricenv.sweep.SweepSettings`.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import platform
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

# The parts of the reproduction. ``common`` loads no kernels, so that ``fricenv reproduce
# --help`` starts at once; the figure parts import the sweeps and are imported when run.
from .common import (
    AMP_PANELS,
    AMP_U0,
    API_NAMES,
    CLI_NAMES,
    ETA_NAMES,
    FULL,
    LINEAR_MATCH_TOL,
    MAP_FIGURES,
    MAX_RESOLUTION,
    NU_MAX,
    PARTS,
    QUICK,
    TIME_HISTORIES,
    Band,
    Report,
    Resolution,
    _ncpu,
    _nthreads,
    _resolution,
    band,
    check_run_args,
    contact_category,
    eta_name,
    map_grid,
)

if TYPE_CHECKING:
    from ..sweep import SweepSettings
    from .amplitude import amplitude_data, fig3, linear_amplitude
    from .maps import figs8_10
    from .time_histories import figs4_7

__all__ = [
    "AMP_PANELS", "AMP_U0", "API_NAMES", "CLI_NAMES", "ETA_NAMES", "FULL",
    "LINEAR_MATCH_TOL", "MAP_FIGURES", "MAX_RESOLUTION", "NU_MAX", "PARTS", "QUICK",
    "TIME_HISTORIES", "Band", "Report", "Resolution", "amplitude_data", "band",
    "check_run_args", "contact_category", "eta_name", "fig3", "figs4_7", "figs8_10",
    "linear_amplitude", "main", "map_grid", "run",
]
#: The names of the figure parts, imported on first use.
_HOMES = {"amplitude_data": "amplitude", "fig3": "amplitude", "linear_amplitude": "amplitude",
          "figs4_7": "time_histories", "figs8_10": "maps"}


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

#: Progress lines go to the package's logger at INFO: the ``fricenv`` command prints them
#: on stderr (``--quiet`` silences them); a program sees them where it configures logging.
LOGGER = logging.getLogger("fricenv")

#: Each part's progress line (the maps add one line per panel, from ``figs8_10``).
PART_LINES = {
    "2": "Fig. 2: the friction laws",
    "3": "Fig. 3: amplitude against eta, simulated cells and the closed form",
    "4-7": "Figs. 4-7: the time histories of the paper's six cases",
    "8-10": "Figs. 8-10: twelve regime-map panels",
}


def run(out: str | os.PathLike, quick: bool = False, docs: str | os.PathLike | None = None,
        n_threads: int | None = None, progress: bool = True, only: Sequence[str] = PARTS,
        resolution: int | None = None) -> Path:
    """Write the figures of the parts ``only`` and ``report.md`` into ``out`` (the map images
    also into ``docs``); return the report's path. Arguments are checked first
    (:func:`check_run_args`), so a bad one fails before anything is computed or written."""
    from .. import plotting
    from ..sweep import SweepSettings
    from .amplitude import fig3
    from .maps import figs8_10
    from .time_histories import figs4_7

    out, quick, docs, n_threads, progress, only, resolution = check_run_args(
        out, quick, docs, n_threads, progress, only, resolution)
    t_start = time.perf_counter()
    res = _resolution(quick, resolution)
    settings = SweepSettings()
    out.mkdir(parents=True, exist_ok=True)
    rep = Report()
    timings: dict[str, float] = {}
    _preamble(rep, quick, settings, res)

    for i, part in enumerate(only, 1):
        LOGGER.info(f"reproduce {i}/{len(only)}: {PART_LINES[part]}")
        if part == "2":
            from .. import plotting

            plotting.save(plotting.friction_laws_figure(), out / "fig2_friction_laws.png")
            rep.add("## Fig. 2: the friction laws", "", "![Fig. 2](fig2_friction_laws.png)",
                    "", "The friction force against the relative velocity for each "
                    "named friction law of fricenv, with "
                    "the stick interval [-x_fs, x_fs] at v_r = 0. The paper states no "
                    "observation on this figure to check.", "")
        elif part == "3":
            fig3(rep, out, res, settings, n_threads, timings)
        elif part == "4-7":
            figs4_7(rep, out, settings, n_threads, timings)
        else:
            figs8_10(rep, out, docs, res, settings, n_threads, progress, timings)

    # -- timings ------------------------------------------------------------------------
    total = time.perf_counter() - t_start
    rep.add("## Run time", "", "| part | seconds |", "|---|---|")
    for k, v in timings.items():
        rep.add(f"| {k} | {v:.1f} |")
    rep.add(f"| **total (this invocation, including compilation and resumed maps)** | "
            f"{total:.1f} |", "",
            f"Machine: {platform.machine()}, {_ncpu()} CPUs, numba threads "
            f"{_nthreads(n_threads)}, Python {platform.python_version()}. Map times are "
            "compute seconds summed over all sessions of a resumed map.", "")
    path = out / "report.md"
    path.write_text(rep.text())
    return path



def _preamble(rep: Report, quick: bool, settings: SweepSettings, res: Resolution) -> None:
    """The report's title, what it compares, and the settings every part uses."""
    rep.add("# Reproduction of the paper's figures", "",
            "Generated by `fricenv reproduce" + (" --quick" if quick else "") + "`. "
            "Paper: *Dry Friction with Various Friction Laws: From Wave Modulated Orbit to "
            "Stick-Slip Modulated* (Modern Mechanical Engineering 5, 2015). Our model, "
            "including the corrections listed in docs/model.md, is simulated with the exact "
            "event-driven kernels of `fricenv` (closed form for Coulomb, "
            "Taylor series with exact switching for the other laws); the paper used "
            "fixed-step RK4 with `sgn`, "
            "which cannot hold a stick phase.", "",
            "Regime labels follow `fricenv.regimes` (criteria in its docstring and in "
            "docs/regimes.md): WM1 = pure slip without contact with v = V, WM2 = reversals only, "
            "SSM1/SSM2 = stick phases with ν ≤ 1 / ν > 1, periodic labels only for integer "
            "ν with a locked response.", "")
    rep.add("## Settings", "",
            f"* initial state: x0 = {settings.x0}, v0 = {settings.v0} (rest; the block "
            "starts slipping backwards relative to the belt)",
            f"* transient: max({settings.transient_min:g}, "
            f"2·{settings.transient_efolds:g}/(λ − b1), {settings.transient_periods:g}·T_mod), "
            f"windows repeated up to {settings.lock_extensions} times at integer ν while the "
            "response is still converging; "
            f"window: max({settings.window_min:g}, {settings.window_periods:g}·T_mod), "
            "T_mod = 2π/(η·dist(ν, ℤ)) (T1 = 2π/η for integer ν)",
            f"* periodicity: ν = p/q with q ≤ {settings.q_max}, ≥ {settings.n_strobe} "
            f"stroboscopic samples at 2πq/η, period ≤ {settings.m_max}, relative tolerance "
            f"{settings.strobe_tol:g}",
            f"* event-driven tolerances (non-Coulomb laws): rtol = {settings.rtol:g}, "
            f"atol = {settings.atol:g}",
            f"* map grid: {res.n_u0} u0 values (geometric) × {res.n_nu} ν values "
            f"(ν = {NU_MAX / res.n_nu:g}, …, {NU_MAX:g}) per panel; u0 ranges: "
            + "; ".join(f"Fig. {f} ({law}): " + ", ".join(
                f"η={eta_name(e)}: [{r[0]:g}, {r[1]:g}]" for e, r in ps)
                for f, (law, ps) in MAP_FIGURES.items()), "")


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog=prog or "fricenv reproduce", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Reproduce the paper's Figs. 2-10 and report each of its observations "
                    "against our simulations.",
        epilog="examples:\n  fricenv reproduce --quick\n"
               "  fricenv reproduce --only 8-10 --resolution 100 --out out/maps")
    ap.add_argument("--quick", action="store_true",
                    help=f"low resolution ({QUICK.n_u0}x{QUICK.n_nu} cells per map panel)")
    ap.add_argument("--out", type=Path, default=None,
                    help="output folder (default out/reproduce or out/reproduce-quick)")
    ap.add_argument("--docs", type=Path, default=None,
                    help="also copy the regime-map images here (e.g. docs/figures)")
    ap.add_argument("--threads", type=int, default=None, help="numba threads (default: all)")
    ap.add_argument("--resolution", type=int, default=None,
                    help="cells per axis of each map panel (overrides the preset)")
    ap.add_argument("--only", default="2,3,4-7,8-10",
                    help="comma-separated parts: 2, 3, 4-7, 8-10 (default: all)")
    ap.add_argument("--no-progress", action="store_true",
                    help="no progress bars (the stage lines stay)")
    ap.add_argument("--quiet", action="store_true",
                    help="no compile notice, stage lines or progress bars")
    a = ap.parse_args(argv)
    out = a.out or Path("out") / ("reproduce-quick" if a.quick else "reproduce")
    only = tuple(s.strip() for s in a.only.split(","))
    try:  # before any map is computed: a late error would leave half a report
        check_run_args(out, a.quick, a.docs, a.threads, not (a.no_progress or a.quiet), only,
                       a.resolution, names=CLI_NAMES)
    except (TypeError, ValueError) as e:
        ap.error(str(e))
    t0 = time.perf_counter()
    from fricenv.interrupts import interrupted, interrupts_redelivered

    try:
        with interrupts_redelivered():
            path = run(out, quick=a.quick, docs=a.docs, n_threads=a.threads,
                       progress=not (a.no_progress or a.quiet), only=only,
                       resolution=a.resolution)
    except KeyboardInterrupt as e:

        return interrupted(ap.prog, e,
                           f"finished maps and cells are kept in {out} (rerun to resume)")
    print(f"wrote {path} and figures in {out} ({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
