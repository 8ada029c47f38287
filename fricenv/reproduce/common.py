"""What every part of the reproduction shares: the paper's cases and panels, the map
grid, the report and its verdicts, map metrics, and the run's argument checks."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..checks import (
    check_bool,
    check_int,
    check_output_dir,
    check_output_file,
    check_path,
    got,
    items_of,
)
from ..layout import (
    ST_STICK_TIME,
)
from ..params import PAPER_CASES

if TYPE_CHECKING:
    from ..maps import RegimeMap

#: Time histories of Figs. 4-7: (figure, panel, overrides, the paper's label).
TIME_HISTORIES: list[tuple[int, str, dict, str]] = [
    (4, "a", PAPER_CASES["4a"], "WM1 (angular modulated, no stick)"),
    (4, "b", PAPER_CASES["4b"], "WM2 (amplitude modulated, no stick)"),
    (5, "a", PAPER_CASES["5a"], "SSM1 (stick phases)"),
    (5, "b", PAPER_CASES["5b"], "SSM1 (stick phases)"),
    (6, "", PAPER_CASES["6"], "SSM2; text: no stick in the whole cycle"),
    (7, "", PAPER_CASES["7"], "caption: periodic oscillation; text: periodic stick-slip"),
]

#: Regime-map panels: figure -> (law, [(eta, (u0_min, u0_max))]). The u0 axis is
#: logarithmic: the stick band spans two to three decades and its far edge moves by a
#: factor of about 100 between panels. Ranges start below the first contact with v = V and
#: end where (away from nu = 1) only reversals remain, found with coarse scans.
MAP_FIGURES: dict[int, tuple[str, list[tuple[float, tuple[float, float]]]]] = {
    8: ("coulomb", [(1 / 9, (0.5, 5000.0)), (1 / 5, (0.2, 1000.0)), (5 / 3, (0.1, 100.0)),
                    (7 / 3, (0.1, 200.0))]),
    9: ("viscous", [(1 / 9, (0.5, 5000.0)), (5 / 17, (0.1, 1000.0)), (5 / 3, (0.1, 100.0)),
                    (7 / 3, (0.1, 200.0))]),
    10: ("stribeck", [(1 / 9, (0.5, 5000.0)), (1 / 5, (0.2, 1000.0)), (3 / 5, (0.1, 1000.0)),
                      (7 / 3, (0.1, 1000.0))]),
}
ETA_NAMES = {1 / 9: "1/9", 1 / 5: "1/5", 5 / 3: "5/3", 7 / 3: "7/3", 5 / 17: "5/17",
             3 / 5: "3/5"}
#: nu axis: (0, 4] in steps of 4 / n_nu, so integers (periodic rows) lie on the grid.
NU_MAX = 4.0

#: The parts a run may do (``--only``), in order.
PARTS = ("2", "3", "4-7", "8-10")

#: Fig. 3 panels (lambda, nu) and the amplitudes drawn.
AMP_PANELS = [(0.25, 1.15), (0.25, 2.5), (0.5, 1.15), (0.5, 2.5)]
AMP_U0 = (0.05, 0.1, 0.2, 0.4)


@dataclass(frozen=True)
class Resolution:
    n_u0: int
    n_nu: int
    n_eta_curve: int
    n_eta_sim: int


FULL = Resolution(200, 200, 600, 30)
QUICK = Resolution(32, 40, 300, 12)
#: Largest --resolution: 12 panels of 1000 x 1000 cells are about 1 GB of maps and many
#: hours; far beyond it a typo would end in a MemoryError.
MAX_RESOLUTION = 1000


def eta_name(eta: float) -> str:
    for k, v in ETA_NAMES.items():
        if abs(k - eta) < 1e-12:
            return v
    return f"{eta:.4g}"


def map_grid(u0_range: tuple[float, float], res: Resolution) -> tuple[np.ndarray, np.ndarray]:
    """(u0, nu) axes of a panel: geometric in u0, uniform in nu with integers on it."""
    u0 = np.geomspace(u0_range[0], u0_range[1], res.n_u0)
    nu = NU_MAX * np.arange(1, res.n_nu + 1) / res.n_nu
    return u0, nu



# ------------------------------------------------------------------------------------------
# Map metrics used by the report
def contact_category(rmap: RegimeMap) -> np.ndarray:
    """0: no contact with v = V, 1: stick phases, 2: reversals only (per cell)."""
    stick = (rmap.n_stick > 0) | (rmap.stats[..., ST_STICK_TIME] > 0)
    rev = rmap.n_reversal > 0
    return np.where(stick, 1, np.where(rev, 2, 0))


@dataclass
class Band:
    nu: np.ndarray
    onset: np.ndarray  # smallest u0 with stick (nan: none)
    end: np.ndarray  # largest u0 with stick (nan: none)
    reaches_wm2: np.ndarray  # column ends in reversal-only cells
    monotone: np.ndarray  # category sequence is 0...0 1...1 2...2 in u0

    def at(self, nu: float) -> tuple[float, float]:
        j = int(np.argmin(np.abs(self.nu - nu)))
        return float(self.onset[j]), float(self.end[j])

    def decades(self) -> np.ndarray:
        return np.log10(self.end / self.onset)


def band(rmap: RegimeMap) -> Band:
    cat = contact_category(rmap)
    u0 = rmap.u0
    onset = np.full(rmap.nu.size, np.nan)
    end = np.full(rmap.nu.size, np.nan)
    mono = np.zeros(rmap.nu.size, dtype=bool)
    for j in range(rmap.nu.size):
        s = np.flatnonzero(cat[:, j] == 1)
        if s.size:
            onset[j], end[j] = u0[s[0]], u0[s[-1]]
        mono[j] = bool(np.all(np.diff(cat[:, j]) >= 0))
    return Band(rmap.nu, onset, end, cat[-1] == 2, mono)


def _median(a: np.ndarray) -> float:
    """Median ignoring NaN (a column without that boundary); NaN, silently, when nothing is
    left (a grid too coarse for the selection, or no band at all)."""
    a = np.asarray(a, dtype=float)
    a = a[~np.isnan(a)]
    return float(np.median(a)) if a.size else math.nan


def _mean(a: np.ndarray) -> float:
    """Mean, NaN (silently) for an empty selection."""
    a = np.asarray(a, dtype=float)
    return float(a.mean()) if a.size else math.nan


def _frac(mask: np.ndarray, sel: np.ndarray) -> float:
    sel = np.broadcast_to(sel, mask.shape)
    return float(mask[sel].mean()) if sel.any() else math.nan


def _straightness(x: np.ndarray, y: np.ndarray) -> float:
    """RMS deviation of y(x) from its least-squares line, relative to the median of y."""
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 3:
        return math.nan
    c = np.polyfit(x[ok], y[ok], 1)
    r = y[ok] - np.polyval(c, x[ok])
    return float(np.sqrt(np.mean(r * r)) / np.median(y[ok]))


# ------------------------------------------------------------------------------------------
class Report:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.rows: list[tuple[str, str, str, str]] = []

    def add(self, *lines: str) -> None:
        self.lines.extend(lines)

    def obs(self, where: str, paper: str, ours: str, verdict: str) -> None:
        self.rows.append((where, paper, ours, verdict))

    def flush_table(self) -> None:
        if not self.rows:
            return
        self.add("| where | the paper states | our simulations | verdict |",
                 "|---|---|---|---|")
        for r in self.rows:
            self.add("| " + " | ".join(c.replace("|", "/") for c in r) + " |")
        self.add("")
        self.rows = []

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


#: Relative match of simulated pure-slip amplitudes to the closed form that counts as
#: agreement in Fig. 3's check (the strobe-window extrema give about 4e-5).
LINEAR_MATCH_TOL = 1e-3


def _verdict(ok: bool | None, partly: bool = False, inputs: Sequence[float] = ()) -> str:
    """The verdict on an observation; "n/a" when any number it rests on is NaN (the grid
    has no cell for that selection), since a comparison with NaN would read as "differ"."""
    if ok is None or any(math.isnan(v) for v in inputs):
        return "n/a"
    return "agree" if ok else ("partly" if partly else "differ")


# ------------------------------------------------------------------------------------------
#: Names of run's arguments in error messages: the Python API's own, or the CLI's options.
API_NAMES = {k: k for k in ("out", "docs", "n_threads", "resolution", "quick", "progress",
                            "only")}
CLI_NAMES = dict(API_NAMES, n_threads="--threads", only="--only", progress="--no-progress",
                 out="--out", docs="--docs", resolution="--resolution", quick="--quick")


def _resolution(quick: bool, resolution: int | None) -> Resolution:
    res = QUICK if quick else FULL
    if resolution is not None:
        res = Resolution(resolution, resolution, res.n_eta_curve, res.n_eta_sim)
    return res


def _map_path(out: Path, fig: int, law: str, eta: float, res: Resolution) -> Path:
    return out / "maps" / f"fig{fig}_{law}_eta{eta:.5f}_{res.n_u0}x{res.n_nu}.npz"


def _outputs(out: Path, only: Sequence[str], res: Resolution) -> list[Path]:
    """Every file a run of the parts ``only`` writes into ``out``."""
    files = [out / "report.md"]
    if "2" in only:
        files.append(out / "fig2_friction_laws.png")
    if "3" in only:
        files.append(out / "fig3_amplitude.png")
    if "4-7" in only:
        files += [out / f"fig{f}_time_history.png" for f in sorted({f for f, *_ in
                                                                     TIME_HISTORIES})]
    if "8-10" in only:
        for fig, (law, panels) in MAP_FIGURES.items():
            files.append(out / f"fig{fig}_regime_maps.png")
            files += [_map_path(out, fig, law, eta, res) for eta, _ in panels]
    return files


def check_run_args(out: object, quick: object = False, docs: object = None,
                   n_threads: object = None, progress: object = True,
                   only: object = PARTS, resolution: object = None,
                   names: dict[str, str] = API_NAMES
                   ) -> tuple[Path, bool, Path | None, int | None, bool, tuple[str, ...],
                              int | None]:
    """:func:`run`'s arguments checked and normalised, before any work: a run of hours must
    not end in a traceback for a bad path found at its end (``names``: how messages call
    each argument). ``TypeError``/``ValueError`` naming the argument.

    Besides types and ranges, every file the run will write (figures, ``report.md``, the map
    caches under ``maps``, copies in ``docs``) must not be a folder, and ``maps`` must not
    be a file. ``docs`` may be ``out`` itself: the images are then already there.
    """
    out = check_path(names["out"], out, "folder")
    quick = check_bool(names["quick"], quick)
    docs = None if docs is None else check_path(names["docs"], docs, "folder")
    progress = check_bool(names["progress"], progress)
    if n_threads is not None:
        from ..sweep import check_n_threads

        try:
            n_threads = check_n_threads(n_threads)
        except (TypeError, ValueError) as e:
            if names["n_threads"] == "n_threads":
                raise
            raise type(e)(f"{names['n_threads']}: {e}") from None
    if resolution is not None:
        resolution = check_int(names["resolution"], resolution)
        if not 2 <= resolution <= MAX_RESOLUTION:
            raise ValueError(f"{names['resolution']} must be 2 to {MAX_RESOLUTION} cells per "
                             f"axis, got {resolution}")
    parts = items_of(only)
    if parts is None or not all(isinstance(k, str) for k in parts):
        raise TypeError(f"{names['only']} must be a list of part names from {list(PARTS)}, "
                        f"{got(only)}")
    bad = sorted(set(parts) - set(PARTS))
    if bad:
        raise ValueError(f"{names['only']}: unknown parts {bad}; expected some of "
                         f"{list(PARTS)}")
    if not parts:
        raise ValueError(f"{names['only']} is empty: nothing to do")
    only = tuple(k for k in PARTS if k in parts)
    check_output_dir(names["out"], out)
    for f in _outputs(out, only, _resolution(quick, resolution)):
        check_output_file(names["out"], f)
    if docs is not None and "8-10" in only:
        check_output_dir(names["docs"], docs)
        for fig in MAP_FIGURES:
            check_output_file(names["docs"], docs / f"fig{fig}_regime_maps.png")
    return out, quick, docs, n_threads, progress, only, resolution


def _ncpu() -> int:

    return os.cpu_count() or 1


def _nthreads(n: int | None) -> int:
    from ..jit import num_threads

    return int(n) if n else num_threads()
