"""Simulate the paper's Figs. 4-7 cases from rest, print their summaries, save a figure.

Usage: python scripts/paper_cases.py [--out DIR] [--t-end T]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import fricenv  # noqa: E402
from fricenv.checks import check_output_dir  # noqa: E402
from fricenv.params import PAPER_CASES as CASES  # noqa: E402


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out"), help="output folder")
    parser.add_argument("--t-end", type=float, default=200.0, help="horizon in tau")
    args = parser.parse_args(argv)
    if not 0.0 < args.t_end < float("inf"):
        parser.error(f"--t-end must be a finite time > 0, got {args.t_end}")
    try:
        check_output_dir("--out", args.out)
    except ValueError as e:
        parser.error(str(e))
    args.out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(len(CASES), 2, figsize=(11, 2.2 * len(CASES)), sharex=True)
    print(f"{'fig':>4} {'nu':>5} {'u0':>5} {'stick frac':>10} {'sticks':>6} {'reversals':>9}"
          f" {'v min':>7} {'v max':>7}")
    for row, (name, kw) in zip(axes, CASES.items(), strict=True):
        p = fricenv.OscillatorParams(**kw)
        tr = fricenv.simulate(p, args.t_end)
        s = tr.summary()
        print(f"{name:>4} {p.nu:5.2f} {p.u0:5.2f} {s['stick_fraction']:10.4f} {s['n_stick']:6d}"
              f" {s['n_reversals']:9d} {s['v_min']:7.3f} {s['v_max']:7.3f}")
        row[0].plot(tr.t, tr.x, lw=0.8)
        row[0].set_ylabel(f"Fig. {name}\nx")
        row[1].plot(tr.t, tr.v, lw=0.8)
        row[1].axhline(p.V, color="k", lw=0.5, ls="--")
        row[1].set_ylabel("v")
    for ax in axes[-1]:
        ax.set_xlabel("τ")
    fig.tight_layout()
    path = args.out / "paper_cases.png"
    fig.savefig(path, dpi=110)
    print(f"figure written to {path}")


if __name__ == "__main__":
    main()
