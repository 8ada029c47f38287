#!/usr/bin/env python
"""The figures of docs/atlas.md: a Coulomb atlas over (u0, nu, eta), its stick-onset
surface over (nu, eta), and four of its (u0, nu) slices.

Usage: ``python scripts/atlas_figures.py [--out DIR] [--store PATH] [--scheduler ADDRESS]``
(the store resumes if the run is stopped; about 480,000 cells, a minute on two cores).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import fricenv
from fricenv.atlas import onset_surface_figure, plot_slice
from fricenv.plotting import _subplots, regime_legend_handles, save

ROOT = Path(__file__).resolve().parents[1]
AXES = {"u0": np.geomspace(0.05, 5000.0, 120),   # tone amplitude, log grid
        "nu": 0.04 * np.arange(1, 101),          # frequency ratio 0.04 ... 4
        "eta": np.geomspace(0.1, 2.5, 40)}       # first tone's frequency
SLICES = (1 / 9, 1 / 5, 5 / 3, 7 / 3)  # Fig. 8's eta values (nearest grid value)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "atlas-figures")
    ap.add_argument("--store", type=Path, default=ROOT / "out" / "atlas_coulomb.zarr")
    ap.add_argument("--scheduler", default=None)
    args = ap.parse_args(argv)
    client = None
    if args.scheduler:
        from distributed import Client

        client = Client(args.scheduler)
    ds = fricenv.atlas("coulomb", AXES, path=args.store, client=client)

    fig = onset_surface_figure(ds, x="nu", y="eta")
    fig.suptitle("Coulomb law (λ = 1/2, V = 1, x_fk = 2.5, x_fs = 4): the least u0 "
                 "with stick phases")
    save(fig, args.out / "atlas_onset_surface.png", dpi=110)

    fig, axes = _subplots(2, 2, figsize=(12.0, 10.2))
    for ax, eta in zip(axes.flat, SLICES, strict=True):
        near = float(ds.eta.sel(eta=eta, method="nearest"))
        plot_slice(ds, ax, eta=eta, title=f"η = {near:.3f}")
    fig.legend(handles=regime_legend_handles(True), loc="outside lower center", ncol=3,
               fontsize=8)
    save(fig, args.out / "atlas_slices.png", dpi=100)
    print(f"wrote {args.out / 'atlas_onset_surface.png'} and {args.out / 'atlas_slices.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
