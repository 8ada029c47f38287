#!/usr/bin/env python
"""The figure and numbers of docs/regimes.md's Lyapunov section: one of the paper's planes
(Fig. 10, Stribeck law, eta = 3/5) labelled by regime beside its largest Lyapunov
exponent per cell, and where the two disagree.

Usage: ``python scripts/lyapunov_plane.py [--out DIR] [--resolution N]`` (default 100 x 100
cells, about a minute on two cores from a filled numba cache).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import fricenv
from fricenv import plotting
from fricenv.regimes import Regime

ROOT = Path(__file__).resolve().parents[1]


def summary(m: fricenv.RegimeMap) -> list[str]:
    """Per regime: cells, and the 5th, 50th and 95th percentiles of the exponent."""
    lines = ["| regime | cells | exponent 5 % | median | 95 % |", "|---|---:|---:|---:|---:|"]
    for r in Regime:
        sel = (m.labels == r) & np.isfinite(m.lyapunov)
        if sel.any():
            q = np.percentile(m.lyapunov[sel], [5, 50, 95])
            lines.append(f"| {r.name} | {int(sel.sum())} | {q[0]:.3f} | {q[1]:.3f} | "
                         f"{q[2]:.3f} |")
    ok = np.isfinite(m.lyapunov)
    lines.append("")
    lines.append(f"cells measured {int(ok.sum())} of {ok.size}; exponent range "
                 f"[{np.min(m.lyapunov[ok]):.3f}, {np.max(m.lyapunov[ok]):.3f}]; "
                 f"above -0.01: {int(np.sum(m.lyapunov[ok] > -0.01))} cells")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "lyapunov")
    ap.add_argument("--resolution", type=int, default=100)
    a = ap.parse_args(argv)
    n = a.resolution
    p = fricenv.OscillatorParams.preset("stribeck", eta=3 / 5)
    u0, nu = np.geomspace(0.1, 1000.0, n), 4.0 * np.arange(1, n + 1) / n
    m = fricenv.regime_map(p, u0=u0, nu=nu, lyapunov=True,
                           path=a.out / f"stribeck_eta0.6_{n}.npz")
    fig, grid = plotting._subplots(1, 2, figsize=(11.0, 4.2))
    axes = grid[0]
    m.plot(ax=axes[0], legend=False, title="regimes (Stribeck law, eta = 3/5)")
    mesh = plotting.draw_lyapunov_map(axes[1], m, title="largest Lyapunov exponent")
    fig.colorbar(mesh, ax=axes[1])
    print(plotting.save(fig, a.out / "lyapunov_plane.png"))
    print("\n".join(summary(m)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
