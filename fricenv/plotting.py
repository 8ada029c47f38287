"""Matplotlib figures of the paper (Figs. 2-10). The simulation core never imports this.

Functions draw on given data and return a ``matplotlib.figure.Figure``; :func:`save` writes
it. Figures are built without ``pyplot``: no global state, no GUI backend, safe in threads and
on headless machines.

Every figure has a title, every axis a label saying its quantity and its unit (the model is
dimensionless, so "(dimensionless)"; the labels are the ``*_LABEL`` constants), and a
legend wherever colours carry meaning: regime maps carry the regimes drawn
(:func:`add_regime_legend`, the same for :meth:`fricenv.RegimeMap.plot` and
:func:`fricenv.atlas.plot_slice`). Stacked panels sharing a time axis label it once, under
the bottom panel.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from .checks import (
    check_finite_real,
    check_output_file,
    check_path,
    got,
    items_of,
    real_array,
)
from .params import FRICTION_LAWS, OscillatorParams
from .regimes import Regime

#: One colour per regime; UNRESOLVED is grey, not-computed cells are white.
REGIME_COLORS: dict[Regime, str] = {
    Regime.UNRESOLVED: "#9e9e9e",
    Regime.WM1: "#bcd9f0",
    Regime.WM2: "#b8e3b0",
    Regime.SSM1: "#f5a35c",
    Regime.SSM2: "#d9453d",
    Regime.PERIODIC_STICK_SLIP: "#ffd400",
    Regime.PERIODIC_OSCILLATION: "#1f4e9c",
    Regime.STUCK: "#7b4a12",
    Regime.DIVERGED: "#c51b7d",
}
REGIME_SHORT: dict[Regime, str] = {
    Regime.UNRESOLVED: "unresolved",
    Regime.WM1: "WM1: pure slip, no contact",
    Regime.WM2: "WM2: reversals, no stick",
    Regime.SSM1: "SSM1: stick-slip, ν ≤ 1",
    Regime.SSM2: "SSM2: stick-slip, ν > 1",
    Regime.PERIODIC_STICK_SLIP: "periodic stick-slip (integer ν)",
    Regime.PERIODIC_OSCILLATION: "periodic oscillation (integer ν)",
    Regime.STUCK: "stuck all window long",
    Regime.DIVERGED: "diverged (motion ran away)",
}
assert set(REGIME_COLORS) == set(REGIME_SHORT) == set(Regime)
LAW_TITLES = {"coulomb": "Coulomb", "viscous": "Coulomb + viscosity",
              "stribeck": "complete (Stribeck)", "exponential": "exponential Stribeck"}
# Laws' parameters as the figures write them.
_SYMBOLS = {"b1": "b_1", "b3": "b_3", "vs": "v_s", "delta": "\\delta", "cv": "c_v"}

#: Axis labels: the quantity, its symbol and its unit (the model is dimensionless).
TIME_LABEL = "time τ (dimensionless)"
X_LABEL = "displacement x (dimensionless)"
V_LABEL = "velocity v (dimensionless)"
U0_LABEL = "tone amplitude $u_0$ (dimensionless)"
NU_LABEL = "frequency ratio ν = ω₂/ω₁ (dimensionless)"
ETA_LABEL = "frequency ratio η = ω₁/ω₀ (dimensionless)"
VR_LABEL = "relative velocity $v_r = v - V$ (dimensionless)"
FORCE_LABEL = "friction force $F(v_r)$ (dimensionless)"
AMPLITUDE_LABEL = "steady-state amplitude of x (dimensionless)"


#: Largest raster :func:`save` writes, in pixels (figure size x dpi squared): 1e8 is about
#: 400 MB of RGBA. dpi = 1e5 on a Fig. 2 ended in ``MemoryError: std::bad_alloc``.
MAX_PIXELS = 1e8


def save(fig: Figure, path: str | os.PathLike, dpi: float = 130) -> Path:
    """Write ``fig`` to ``path`` and return the path written, creating its folder.

    The format comes from the suffix; a path without one gets ``.png``. Everything is
    checked before the folder is made (``TypeError``/``ValueError`` naming ``fig``, ``path``
    or ``dpi``): a known format, no folder at ``path``, a positive ``dpi`` giving at most
    ``MAX_PIXELS`` pixels. The figure is left open and usable: it was built without
    ``pyplot``, so nothing holds it and there is nothing to close.
    """
    if not isinstance(fig, Figure):
        raise TypeError(f"fig must be a matplotlib Figure, {got(fig)}")
    path = check_path("path", path, "file name")
    if not path.name or path.is_dir():  # (with .png appended it would be written beside)
        raise ValueError(f"path must name a file, got the folder {str(path)!r}")
    if not path.suffix:
        path = path.with_name(path.name + ".png")
    fmt = path.suffix[1:].lower()
    formats = fig.canvas.get_supported_filetypes()
    if fmt not in formats:
        raise ValueError(f"path {str(path)!r}: unknown image format {fmt!r}; expected a "
                         f"suffix in {sorted(formats)}")
    check_output_file("path", path)
    dpi = check_finite_real("dpi", dpi)
    w, h = fig.get_size_inches()
    if not dpi > 0 or w * h * dpi * dpi > MAX_PIXELS:
        raise ValueError(f"dpi must be > 0 and give at most {MAX_PIXELS:g} pixels for this "
                         f"{w:g} x {h:g} inch figure (dpi <= {(MAX_PIXELS / (w * h)) ** 0.5:.0f})"
                         f", got {dpi!r}")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi, bbox_inches="tight", format=fmt)
    return path


class ShowableFigure(Figure):
    """A ``Figure`` that shows itself as an image in IPython and Jupyter.

    The figures here are built without ``pyplot`` (no global state, no GUI backend), so no
    notebook backend knows them: a cell ending in one would print ``<Figure size ...>``.
    ``_repr_png_`` is IPython's hook for a rich display.
    """

    def _repr_png_(self) -> bytes:
        buf = io.BytesIO()
        self.savefig(buf, format="png", bbox_inches="tight")
        return buf.getvalue()


def _subplots(nrows: int, ncols: int, figsize: tuple[float, float], **kw: Any
              ) -> tuple[Figure, np.ndarray]:
    fig = ShowableFigure(figsize=figsize, layout="constrained")
    kw.setdefault("squeeze", False)
    return fig, fig.subplots(nrows, ncols, **kw)


# -- Fig. 2 --------------------------------------------------------------------------------
def friction_laws_figure(xfk: float = 2.5, xfs: float = 4.0, vr_max: float = 3.0) -> Figure:
    """Fig. 2: the friction force ``F(v_r)`` of every named law (:data:`FRICTION_LAWS`):
    the paper's three, ``x_f sgn(v_r) - b1 v_r + b3 v_r^3``, and the exponential Stribeck
    law, each drawn by its own module's force.

    At ``v_r = 0`` the force is set-valued, ``[-x_fs, x_fs]`` (stick), drawn as a bar.
    """
    names = list(FRICTION_LAWS)
    fig, axes = _subplots(1, len(names), figsize=(3.7 * len(names), 3.4), sharey=True)
    axes = axes[0]
    vr = np.linspace(-vr_max, vr_max, 801)
    for ax, name, tag in zip(axes, names, "abcdefgh", strict=False):
        p = OscillatorParams.preset(name, xfk=xfk, xfs=xfs)
        law, values = p.law_spec, p.law_values()
        for side in (vr < 0, vr > 0):
            v = vr[side]
            ax.plot(v, law.force(v, values, xfk, xfs), color="C0", lw=2,
                    label="slip" if side[0] else None)
        ax.plot([0, 0], [-xfs, xfs], color="C3", lw=3, label="stick: $|F| \\leq x_{fs}$")
        ax.axhline(0, color="k", lw=0.5)
        ax.axvline(0, color="k", lw=0.5)
        shown = ", ".join(f"${_SYMBOLS.get(k, k)}$={v:g}" for k, v in values.items())
        ax.set_title(f"({tag}) {LAW_TITLES.get(name, name)}" + (f": {shown}" if shown else ""),
                     fontsize=9)
        ax.set_xlabel(VR_LABEL)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(FORCE_LABEL)  # (the panels share their y axis)
    axes[0].legend(loc="upper left", fontsize=8)
    fig.suptitle(f"Fig. 2: friction force against relative velocity ($x_{{fk}}$ = {xfk:g}, "
                 f"$x_{{fs}}$ = {xfs:g}); (d) is fricenv's exponential Stribeck law")
    return fig


# -- Fig. 3 --------------------------------------------------------------------------------
def amplitude_figure(panels: Sequence[dict],
                     suptitle: str = "Fig. 3: steady-state amplitude against η, Coulomb law, "
                                     "V = 1") -> Figure:
    """Fig. 3: steady-state amplitude versus eta, under the title ``suptitle``.

    Each panel dict has ``lam``, ``nu``, ``eta`` (curve grid), ``curves`` {u0: amplitude},
    and optionally ``sim`` {u0: (eta, amplitude, contact_bool)}: simulated half peak-to-peak
    of x, filled where the window was pure slip, open where the block touched v = V.
    """
    n = len(panels)
    ncol = 2 if n > 1 else 1
    nrow = (n + ncol - 1) // ncol
    fig, axes = _subplots(nrow, ncol, figsize=(5.6 * ncol, 3.9 * nrow))
    for k, (ax, pan) in enumerate(zip(axes.flat, panels, strict=False)):
        for i, (u0, amp) in enumerate(sorted(pan["curves"].items())):
            ax.plot(pan["eta"], amp, color=f"C{i}", lw=1.6, label=f"$u_0$ = {u0:g} (theory)")
            if "sim" in pan and u0 in pan["sim"]:
                e, a, contact = pan["sim"][u0]
                e, a, contact = np.asarray(e), np.asarray(a), np.asarray(contact, bool)
                ax.plot(e[~contact], a[~contact], "o", ms=4, color=f"C{i}")
                ax.plot(e[contact], a[contact], "o", ms=4, mfc="none", color=f"C{i}")
        ax.set_title(f"({'abcd'[k] if k < 4 else k}) λ = {pan['lam']:g}, ν = {pan['nu']:g}")
        ax.set_xlabel(ETA_LABEL)
        ax.set_ylabel(AMPLITUDE_LABEL)
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    handles += [Line2D([], [], ls="", marker="o", color="k", ms=4),
                Line2D([], [], ls="", marker="o", mfc="none", color="k", ms=4)]
    labels += ["simulated, pure slip", "simulated, with contact (stick / reversal)"]
    axes.flat[0].legend(handles, labels, fontsize=7, loc="upper right")
    fig.suptitle(suptitle)
    return fig


# -- Figs. 4-7 -----------------------------------------------------------------------------
def params_title(p: OscillatorParams) -> str:
    """A short title naming a plant's law and excitation."""
    return (f"{LAW_TITLES.get(p.law, p.law)}: η = {p.eta:.4g}, ν = {p.nu:.4g}, "
            f"u0 = {p.u0:.4g}")


def _run_dict(run: Any) -> dict[str, Any]:
    """A time-history run as a dict: a ``Trajectory`` (anything with ``t, x, v, mode`` and
    ``params``) or a dict with those arrays, ``title`` and ``V``."""
    if isinstance(run, dict):
        missing = [k for k in ("t", "x", "v", "mode") if k not in run]
        if missing:
            raise TypeError(f"a run dict needs keys t, x, v, mode; missing {missing}")
        return run
    if all(hasattr(run, k) for k in ("t", "x", "v", "mode", "params")):
        p = run.params
        return {"t": run.t, "x": run.x, "v": run.v, "mode": run.mode, "V": p.V,
                "title": params_title(p)}
    raise TypeError(f"each run must be a Trajectory or a dict of arrays, {got(run)}")


def draw_velocity(ax: Axes, t: np.ndarray, v: np.ndarray, mode: np.ndarray, V: float) -> None:
    """v(t) with the belt speed dashed and stick intervals (``mode == 0``) shaded."""
    ax.plot(t, v, color="C1", lw=0.9, label="velocity v")
    ax.axhline(V, color="k", ls="--", lw=0.8, label="belt speed V")
    stuck = np.asarray(mode) == 0
    if stuck.any():
        ax.fill_between(t, 0, 1, where=stuck, transform=ax.get_xaxis_transform(),
                        color="C3", alpha=0.18, lw=0, label="stick")
    ax.set_ylabel(V_LABEL)
    ax.set_xlabel(TIME_LABEL)
    ax.legend(fontsize=7, loc="lower right")
    ax.grid(alpha=0.3)


def draw_displacement(ax: Axes, t: np.ndarray, x: np.ndarray, time_label: bool = True
                      ) -> None:
    """x(t), one line (no legend: its colour means nothing); ``time_label=False`` for a
    panel above another that labels the shared time axis."""
    ax.plot(t, x, color="C0", lw=0.9)
    ax.set_ylabel(X_LABEL)
    if time_label:
        ax.set_xlabel(TIME_LABEL)
    ax.grid(alpha=0.3)


def time_history_figure(runs: Sequence[object], suptitle: str | None = None) -> Figure:
    """Figs. 4-7: displacement (top) and velocity (bottom) per run, one column each, the
    time axis labelled once, under the bottom panels. The title is ``suptitle``, or
    without it each column's run title alone.

    Each run is a :class:`~fricenv.Trajectory`, or a dict with ``t, x, v, mode`` arrays,
    ``title`` and ``V``; stick intervals (``mode == 0``) are shaded in the velocity panel
    and ``v = V`` is dashed.
    """
    items = items_of(runs)
    if items is None:
        raise TypeError(f"runs must be a list of Trajectory (or of dicts), {got(runs)}")
    if not items:
        raise ValueError("runs is empty: nothing to draw")
    dicts = [_run_dict(r) for r in items]
    n = len(dicts)
    fig, axes = _subplots(2, n, figsize=(5.6 * n, 5.6), sharex="col")
    for j, run in enumerate(dicts):
        ax_x, ax_v = axes[0, j], axes[1, j]
        t, x, v, mode = (np.asarray(run[k]) for k in ("t", "x", "v", "mode"))
        draw_displacement(ax_x, t, x, time_label=False)
        ax_x.set_title(run.get("title") or f"run {j + 1}", fontsize=10)
        draw_velocity(ax_v, t, v, mode, run.get("V", 1.0))
    if suptitle:
        fig.suptitle(suptitle)
    return fig


# -- Figs. 8-10 ----------------------------------------------------------------------------
def _edges(c: np.ndarray, log: bool) -> np.ndarray:
    c = np.asarray(c, dtype=float)
    if c.size == 1:
        d = 0.5 * (abs(c[0]) if c[0] else 1.0)
        return np.array([c[0] - d, c[0] + d])
    z = np.log(c) if log else c
    mid = 0.5 * (z[1:] + z[:-1])
    e = np.concatenate([[z[0] - (mid[0] - z[0])], mid, [z[-1] + (z[-1] - mid[-1])]])
    return np.exp(e) if log else e


def _is_log(u0: np.ndarray) -> bool:
    u0 = np.asarray(u0, dtype=float)
    if u0.size < 3 or np.any(u0 <= 0):
        return False
    r = u0[1:] / u0[:-1]
    return bool(np.allclose(r, r[0], rtol=1e-6) and r[0] > 1.0 + 1e-9)


def _band_edge(stick: np.ndarray, ue: np.ndarray, ne: np.ndarray, which: str
               ) -> tuple[np.ndarray, np.ndarray]:
    """Step curve through cell edges: left edge of the first stick cell of each nu row
    (``"first"``) or right edge of the last one (``"last"``); NaN breaks rows without stick."""
    xs, ys = [], []
    for j in range(stick.shape[1]):
        i = np.flatnonzero(stick[:, j])
        if i.size == 0:
            xs.append(np.nan)
            ys.append(np.nan)
            continue
        x = ue[i[0]] if which == "first" else ue[i[-1] + 1]
        xs += [x, x]
        ys += [ne[j], ne[j + 1]]
    return np.array(xs), np.array(ys)


def regime_cmap() -> tuple[ListedColormap, BoundaryNorm]:
    colors = ["#ffffff"] + [REGIME_COLORS[r] for r in Regime]  # index 0: not computed
    cmap = ListedColormap(colors)
    norm = BoundaryNorm(np.arange(-1.5, len(Regime) + 0.5), cmap.N)
    return cmap, norm


def _axis(name: str, value: object) -> np.ndarray:
    a = real_array(value, f"{name} must be a 1-d array of real numbers")
    if a.ndim != 1 or a.size == 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a non-empty 1-d array of finite numbers, got "
                         f"shape {a.shape}")
    return a


def _sorted_grid(rmap: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``rmap``'s ``(u0, nu, labels)`` with both axes in increasing order. A map may be
    computed on an unsorted grid (cells are independent), but cell edges and boundary lines
    need order: drawn as given they were meaningless. A repeated value has no cell of its
    own, so it is a ``ValueError`` naming the axis."""
    for k in ("u0", "nu", "labels"):
        if not hasattr(rmap, k):
            raise TypeError(f"rmap must be a RegimeMap (with u0, nu and labels), {got(rmap)}")
    u0, nu = _axis("rmap.u0", rmap.u0), _axis("rmap.nu", rmap.nu)
    labels = np.asarray(rmap.labels)
    if labels.shape != (u0.size, nu.size):
        raise ValueError(f"rmap.labels must have shape (u0, nu) = {(u0.size, nu.size)}, got "
                         f"{labels.shape}")
    iu, jn = np.argsort(u0, kind="stable"), np.argsort(nu, kind="stable")
    u0, nu, labels = u0[iu], nu[jn], labels[np.ix_(iu, jn)]
    for name, a in (("rmap.u0", u0), ("rmap.nu", nu)):
        if np.any(np.diff(a) == 0):
            raise ValueError(f"{name} must not repeat a value, got "
                             f"{float(a[np.flatnonzero(np.diff(a) == 0)[0]])!r} twice")
    return u0, nu, labels


def draw_lyapunov_map(ax: Axes, rmap: Any, title: str | None = None) -> Any:
    """One (u0, nu) panel coloured by each cell's largest Lyapunov exponent
    (``rmap.lyapunov``; grey where not measured), on a diverging scale centred on 0, so
    that chaos (> 0) and neutral motion (0) stand apart from the stable (< 0). Returns
    the mesh, for a colour bar."""
    order_u, order_nu = np.argsort(rmap.u0), np.argsort(rmap.nu)
    u0, nu = rmap.u0[order_u], rmap.nu[order_nu]
    values = np.asarray(rmap.lyapunov)[np.ix_(order_u, order_nu)]
    log = _is_log(u0)
    finite = values[np.isfinite(values)]
    span = float(np.max(np.abs(finite))) if finite.size else 1.0
    cmap = plt_colormap("RdBu_r").with_extremes(bad="0.8")
    mesh = ax.pcolormesh(_edges(u0, log), _edges(nu, False), values.T, cmap=cmap,
                         vmin=-span, vmax=span, shading="flat", rasterized=True)
    if log:
        ax.set_xscale("log")
    ax.set_xlabel("u0")
    ax.set_ylabel("nu")
    if title:
        ax.set_title(title, fontsize=10)
    return mesh


def plt_colormap(name: str) -> Any:
    """A registered matplotlib colormap (a copy, safe to modify)."""
    import matplotlib

    return matplotlib.colormaps[name].copy()


def draw_regime_map(ax: Axes, rmap: Any, boundaries: bool = True,
                    title: str | None = None, legend: bool = False) -> None:
    """One (u0, nu) panel: u0 on x (log if the grid is geometric), nu on y.

    Cells are coloured by regime. The solid black line is the first boundary (smallest u0
    with stick phases, per nu row), the dashed one the second (largest u0 with stick phases;
    beyond it only reversals). The first contact with v = V as u0 grows is always a stick in
    our maps (grazing contacts stick), so the first boundary is also the onset of contact.
    Rows at integer nu, where the periodic labels live, are redrawn as thick strips so that a
    single grid row stays visible. ``legend``: the regimes drawn, right of the panel
    (:func:`add_regime_legend`; a figure of several panels has one shared legend instead).
    """
    u0, nu, labels = _sorted_grid(rmap)
    log = _is_log(u0)
    cmap, norm = regime_cmap()
    ax.pcolormesh(_edges(u0, log), _edges(nu, False), labels.T.astype(float), cmap=cmap,
                  norm=norm, shading="flat", rasterized=True)
    if log:
        ax.set_xscale("log")
    if boundaries:
        stick = np.isin(labels, [Regime.SSM1, Regime.SSM2, Regime.PERIODIC_STICK_SLIP])
        ue, ne = _edges(u0, log), _edges(nu, False)
        for which in ("first", "last"):
            xs, ys = _band_edge(stick, ue, ne, which)
            ax.plot(xs, ys, color="k", lw=1.2 if which == "first" else 1.0,
                    ls="-" if which == "first" else "--")
    ints = np.flatnonzero(np.isclose(nu, np.round(nu), atol=1e-9) & (nu > 0))
    if nu.size > 40:
        ue = _edges(u0, log)
        for j in ints:
            for i in range(u0.size):
                lab = int(labels[i, j])
                if lab in (Regime.PERIODIC_OSCILLATION, Regime.PERIODIC_STICK_SLIP):
                    ax.plot([ue[i], ue[i + 1]], [nu[j], nu[j]], color=REGIME_COLORS[Regime(lab)],
                            lw=3.0, solid_capstyle="butt")
    ax.set_xlabel(U0_LABEL + (", log scale" if log else ""))
    ax.set_ylabel(NU_LABEL)
    if title:
        ax.set_title(title, fontsize=10)
    if legend:
        add_regime_legend(ax, labels, boundaries)


def add_regime_legend(ax: Axes, labels: np.ndarray, boundaries: bool = True) -> None:
    """The legend of a single regime map, right of ``ax``: a patch for each regime among
    ``labels`` (in ``Regime`` order), then the boundary lines if drawn. Used by
    :meth:`fricenv.RegimeMap.plot` and :func:`fricenv.atlas.plot_slice` alike, so that a
    map reads the same wherever it is drawn."""
    present = {int(v) for v in np.unique(np.asarray(labels))}
    regimes = list(Regime)  # (the handles' order; the boundary lines follow)
    handles = [h for k, h in enumerate(regime_legend_handles(True, boundaries))
               if k >= len(regimes) or int(regimes[k]) in present]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=7,
              title="regime", title_fontsize=8, borderaxespad=0.0)


def regime_legend_handles(include_unresolved: bool = True, boundaries: bool = True) -> list:
    """Legend entries for a regime map: a patch per regime, then the two boundary lines
    that ``draw_regime_map`` draws (``boundaries=False`` leaves them out, for a plot of
    labels alone)."""
    hs: list[Artist] = [
        Patch(facecolor=REGIME_COLORS[r], edgecolor="k", lw=0.4, label=REGIME_SHORT[r])
        for r in Regime if include_unresolved or r != Regime.UNRESOLVED]
    if boundaries:
        hs.append(Line2D([], [], color="k", lw=1.2, label="1st boundary: stick begins"))
        hs.append(Line2D([], [], color="k", lw=1.0, ls="--",
                         label="2nd boundary: last stick (only reversals beyond)"))
    return hs


def map_title(rmap: Any) -> str:
    """A regime map's plant in a few words (law and eta), or "regime map" for a map that
    carries no parameters."""
    p = getattr(rmap, "params", None)
    if not isinstance(p, OscillatorParams):
        return "regime map"
    return f"{LAW_TITLES.get(p.law, p.law)} law, η = {p.eta:.4g}"


def regime_maps_figure(maps: Sequence[object], titles: Sequence[str] | None = None,
                       suptitle: str | None = None) -> Figure:
    """Figs. 8-10: regime maps two per row (the paper's four in a 2 x 2 grid) with one shared
    legend. ``titles``, if given, has one str per map (a short list used to end in an
    ``IndexError``); without them each panel is titled by its plant (:func:`map_title`)."""
    items = items_of(maps)
    if items is None:
        raise TypeError(f"maps must be a list of RegimeMap, {got(maps)}")
    if not items:
        raise ValueError("maps is empty: nothing to draw")
    maps = items
    if titles is not None:
        tl = items_of(titles)
        if tl is None or not all(isinstance(t, str) for t in tl):
            raise TypeError(f"titles must be a list of str (one per map) or None, "
                            f"{got(titles)}")
        if len(tl) != len(maps):
            raise ValueError(f"titles must have one entry per map ({len(maps)}), got "
                             f"{len(tl)}: {tl!r}")
        titles = tl
    n = len(maps)
    ncol = 2 if n > 1 else 1
    nrow = (n + ncol - 1) // ncol
    if titles is None:  # (each panel says which plant it is)
        titles = [map_title(m) for m in maps]
    fig, axes = _subplots(nrow, ncol, figsize=(6.0 * ncol, 4.6 * nrow + 1.0))
    for k, (ax, m) in enumerate(zip(axes.flat, maps, strict=False)):
        draw_regime_map(ax, m, title=titles[k])
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    unresolved = any(np.any(np.asarray(m.labels) == Regime.UNRESOLVED) for m in maps)
    fig.legend(handles=regime_legend_handles(True), loc="outside lower center",
               ncol=3, fontsize=8, title=None if not unresolved else
               "grey cells: solver stopped (event cap)")
    if suptitle:
        fig.suptitle(suptitle)
    return fig
