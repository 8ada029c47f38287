"""Views of an atlas: a 2-d slice drawn as a regime map, the stick boundaries over the
remaining axes, and the stick-onset surface. The only atlas module that imports
matplotlib; figures are built without ``pyplot`` (see :mod:`fricenv.plotting`)."""

from __future__ import annotations

import json
from types import SimpleNamespace
from typing import Any

import numpy as np
import xarray as xr
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..checks import got
from ..params import OscillatorParams
from ..plotting import (
    ETA_LABEL,
    LAW_TITLES,
    NU_LABEL,
    U0_LABEL,
    _subplots,
    draw_regime_map,
    regime_legend_handles,
)
from ..regimes import Regime

#: Axis labels of the swept parameters, each with its unit: the model is dimensionless
#: (others are labelled by their name).
AXIS_LABELS = {"u0": U0_LABEL, "nu": NU_LABEL, "eta": ETA_LABEL,
               "lam": "damping λ (dimensionless)", "V": "belt speed V (dimensionless)",
               "xfk": "kinetic friction $x_{fk}$ (dimensionless)",
               "xfs": "static friction $x_{fs}$ (dimensionless)",
               "b1": "viscous coefficient $b_1$ (dimensionless)",
               "b3": "cubic coefficient $b_3$ (dimensionless)",
               "vs": "Stribeck speed $v_s$ (dimensionless)",
               "delta": "Stribeck shape exponent $\\delta$",
               "cv": "viscous coefficient $c_v$ (dimensionless)"}


def _label(name: str) -> str:
    return AXIS_LABELS.get(name, f"{name} (dimensionless)")


def _law(ds: xr.Dataset) -> str:
    """The atlas's friction law in words, from its stored base parameters."""
    try:
        law = OscillatorParams(**json.loads(str(ds.attrs["base"]))).law
    except (KeyError, TypeError, ValueError):
        return "regime atlas"
    return f"{LAW_TITLES.get(law, law)} law"


def _slice_title(ds: xr.Dataset, lab: xr.DataArray) -> str:
    """The law and the value of each axis the slice fixes."""
    fixed = [f"{d} = {float(lab[d]):.4g}" for d in ds.dims if d in lab.coords
             and d not in lab.dims]
    return ", ".join([_law(ds), *fixed])


def _check_atlas(ds: object) -> xr.Dataset:
    if not isinstance(ds, xr.Dataset) or "label" not in ds:
        raise TypeError(f"ds must be an atlas (an xarray.Dataset with a label), {got(ds)}")
    return ds


def stick_labels() -> list[int]:
    """The labels of regimes with stick phases (from ``Regime`` itself)."""
    return [int(r) for r in Regime if r.has_stick]


def stick_boundaries(ds: xr.Dataset, along: str = "u0") -> xr.Dataset:
    """The stick-onset and last-stick boundaries along ``along`` over the other axes.

    ``onset``: the smallest grid value of ``along`` whose cell has stick phases;
    ``last_stick``: the largest (beyond it, only reversals). NaN where no cell has stick.
    Both are resolved to the grid's spacing. Works on lazy (store-backed) atlases too.
    """
    ds = _check_atlas(ds)
    if along not in ds.dims:
        raise ValueError(f"along must be one of the atlas's axes {list(ds.dims)}, got "
                         f"{along!r}")
    stick = ds["label"].isin(stick_labels())
    coord = ds[along].broadcast_like(stick)
    out = xr.Dataset({"onset": coord.where(stick).min(along),
                      "last_stick": coord.where(stick).max(along)})
    out["onset"].attrs["long_name"] = f"least {along} with stick phases"
    out["last_stick"].attrs["long_name"] = f"greatest {along} with stick phases"
    return out.drop_vars("q", errors="ignore")


def _slice_2d(ds: xr.Dataset, x: str, y: str, sel: dict) -> xr.DataArray:
    """The label over ``(x, y)``, the other axes selected by ``sel`` (nearest value)."""
    for name in (x, y):
        if name not in ds.dims:
            raise ValueError(f"{name!r} is not an axis of the atlas {list(ds.dims)}")
    if x == y:
        raise ValueError(f"x and y must be two different axes, got {x!r} twice")
    rest = [d for d in ds.dims if d not in (x, y)]
    missing = [d for d in rest if d not in sel and ds.sizes[d] > 1]
    if missing:
        raise ValueError(f"select a value of each other axis: {missing} (e.g. "
                         f"{missing[0]}={float(ds[missing[0]][0])!r})")
    unknown = sorted(set(sel) - set(rest))
    if unknown:
        raise ValueError(f"{unknown} are not other axes of the atlas ({rest})")
    lab = ds["label"].sel({k: v for k, v in sel.items()}, method="nearest")
    lab = lab.squeeze([d for d in rest if d in lab.dims])  # (kept as scalar coordinates)
    return lab.transpose(x, y)


def plot_slice(ds: xr.Dataset, ax: Axes | None = None, x: str = "u0", y: str = "nu",
               boundaries: bool | None = None, title: str | None = None,
               legend: bool = True, **sel: Any) -> Axes:
    """Draw the 2-d slice ``(x, y)`` of an atlas as a regime map, the other axes fixed by
    keyword (nearest grid value), e.g. ``plot_slice(ds, eta=0.2)``: the colours and the
    legend of :meth:`fricenv.RegimeMap.plot`. The stick boundaries are drawn along ``x``
    (default: when ``x`` is u0). ``title``: default, the law and the values the slice
    fixes. Returns the axes drawn on."""
    ds = _check_atlas(ds)
    lab = _slice_2d(ds, x, y, sel)
    if ax is None:
        ax = _subplots(1, 1, figsize=(8.0, 4.6))[1].flat[0]
    view = SimpleNamespace(u0=lab[x].values, nu=lab[y].values, labels=lab.values)
    draw_regime_map(ax, view, boundaries=(x == "u0") if boundaries is None else boundaries,
                    title=_slice_title(ds, lab) if title is None else title, legend=legend)
    ax.set_xlabel(_label(x) + (", log scale" if ax.get_xscale() == "log" else ""))
    ax.set_ylabel(_label(y))
    return ax


def slice_figure(ds: xr.Dataset, x: str = "u0", y: str = "nu", panel: str | None = None,
                 **sel: Any) -> Figure:
    """One slice per value of the axis ``panel`` (two per row) with a shared legend; the
    atlas's Figs. 8-10. Other axes are fixed by keyword as in :func:`plot_slice`."""
    ds = _check_atlas(ds)
    values = [None] if panel is None else list(ds[panel].values)
    ncol = 2 if len(values) > 1 else 1
    nrow = -(-len(values) // ncol)
    fig, axes = _subplots(nrow, ncol, figsize=(6.0 * ncol, 4.6 * nrow + 1.0))
    for ax, v in zip(axes.flat, values, strict=False):
        extra: dict[str, Any] = {} if v is None or panel is None else {panel: v}
        plot_slice(ds, ax, x, y, title=None if v is None else f"{panel} = {v:.4g}",
                   legend=False, **sel, **extra)
    for ax in list(axes.flat)[len(values):]:
        ax.set_visible(False)
    fig.legend(handles=regime_legend_handles(True, boundaries=(x == "u0")),
               loc="outside lower center", ncol=3, fontsize=8)
    fixed = ", ".join(f"{k} = {v:.4g}" for k, v in sel.items())
    fig.suptitle(f"{_law(ds)}: regimes over ({x}, {y})" + (f", {fixed}" if fixed else ""))
    return fig


def onset_surface_figure(ds: xr.Dataset, x: str = "nu", y: str = "eta",
                         along: str = "u0", **sel: float) -> Figure:
    """The stick-onset value of ``along`` as a surface over ``(x, y)`` (3-d, log height)
    beside its map, other axes fixed by keyword (nearest value)."""
    bounds = stick_boundaries(_check_atlas(ds), along)
    onset = bounds["onset"]
    if sel:
        onset = onset.sel(sel, method="nearest")
    rest = [d for d in onset.dims if d not in (x, y)]
    if rest or x not in onset.dims or y not in onset.dims:
        raise ValueError(f"the onset must lie over ({x}, {y}) once the other axes are "
                         f"selected; it has the axes {list(onset.dims)}")
    z = np.log10(onset.transpose(y, x).values)
    X, Y = np.meshgrid(onset[x].values, onset[y].values)
    fig = Figure(figsize=(12.0, 5.0), layout="constrained")
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax3.plot_surface(X, Y, np.ma.masked_invalid(z), cmap="viridis", linewidth=0,
                     antialiased=True, rcount=200, ccount=200)
    ax3.set_xlabel(_label(x))
    ax3.set_ylabel(_label(y))
    ax3.set_zlabel(f"log10 of the onset {along} (dimensionless)")
    ax3.view_init(elev=28, azim=-130)
    ax2 = fig.add_subplot(1, 2, 2)
    mesh = ax2.pcolormesh(X, Y, z, cmap="viridis", shading="nearest")
    ax2.set_xlabel(_label(x))
    ax2.set_ylabel(_label(y))
    fig.colorbar(mesh, ax=ax2, label=f"log10 of the least {along} with stick phases "
                                     "(white: none on the grid)")
    ax3.set_title("surface")
    ax2.set_title("map")
    fig.suptitle(f"{_law(ds)}: stick onset in {along} over ({x}, {y})")
    return fig
