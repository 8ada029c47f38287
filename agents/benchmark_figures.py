"""The control benchmark's figures: returns, performance profiles and generalisation.

Drawn from the entries that ``fricenv_agents.benchmark_rows`` scored. matplotlib is imported
only when a figure is drawn, so that the benchmark's rows and runs load without it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from . import statistics as S
from .benchmark_rows import BOOT_SEED, CONDITIONS, Results, Row, row_keys, short_name


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_returns(rows: Sequence[Row], results: Results, path: Path) -> None:
    """Each scene's IQM episode cost (-return) per controller with its 95 % interval, on a
    log axis: the learned and model-based controllers lie one to two orders of magnitude
    below the baselines."""
    plt = _pyplot()
    scenes = list(results)
    fig, axes = plt.subplots(1, len(scenes), figsize=(3.4 * len(scenes), 3.2), squeeze=False,
                             sharey=True)
    keys = row_keys(rows, results)
    for ax, scene in zip(axes[0], scenes, strict=True):
        for y, key in enumerate(keys):
            e = results[scene].get(key)
            if e is None:
                continue
            iv = e.interval("ret")
            cost, lo, hi = -iv.estimate, -iv.hi, -iv.lo
            floor = max(lo, 0.1 * cost)  # (a log axis has no room below zero)
            ax.errorbar(cost, y, xerr=[[cost - floor], [hi - cost]], fmt="o", color=f"C{y}",
                        ms=5, capsize=2)
        ax.set_xscale("log")
        ax.set_yticks(range(len(keys)), [short_name(rows, k) for k in keys], fontsize=8)
        ax.grid(axis="x", alpha=0.3)
        ax.set_title(scene, fontsize=10)
        ax.set_xlabel("IQM episode cost = -return (lower is better)", fontsize=8)
    axes[0][0].invert_yaxis()  # (shared: once for all) the table's order, top down
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_profiles(rows: Sequence[Row], results: Results, path: Path) -> None:
    """Performance profiles: per scene, the fraction of each controller's episodes (all its
    models) whose cost (-return) is at most tau, over a log grid of tau, with a 95 %
    bootstrap band. A curve above and left of another is better at every threshold."""
    plt = _pyplot()
    scenes = list(results)
    fig, axes = plt.subplots(1, len(scenes), figsize=(3.6 * len(scenes), 3.9), squeeze=False,
                             sharey=True)
    keys = row_keys(rows, results)
    handles: dict[str, Any] = {}
    for ax, scene in zip(axes[0], scenes, strict=True):
        present = [k for k in keys if k in results[scene]]
        taus = S.tau_grid([-results[scene][k].matrix("ret") for k in present])
        for key in present:
            e = results[scene][key]
            prof = S.performance_profile(-e.matrix("ret"), taus, strata=e.n_seeds,
                                         seed=BOOT_SEED)
            color = f"C{keys.index(key)}"
            # (an empirical distribution: each value holds up to the next threshold)
            handles[key], = ax.plot(taus, prof.fraction, color=color, lw=1.2,
                                    drawstyle="steps-post")
            ax.fill_between(taus, prof.lo, prof.hi, color=color, alpha=0.2, lw=0,
                            step="post")
        ax.set_xscale("log")
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
        ax.set_title(scene, fontsize=10)
        ax.set_xlabel("episode cost τ = -return", fontsize=8)
    axes[0][0].set_ylabel("fraction of episodes with cost ≤ τ", fontsize=8)
    fig.legend([handles[k] for k in keys if k in handles],
               [short_name(rows, k) for k in keys if k in handles], loc="lower center",
               ncol=min(len(handles), 8), fontsize=7, frameon=False)
    fig.tight_layout(rect=(0.0, 0.08, 1.0, 1.0))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_generalisation(rows: Sequence[Row], summary: dict[str, dict[str, dict[str, Any]]],
                        path: Path) -> None:
    """Stick cut per condition and controller, with the 95 % intervals as error bars."""
    plt = _pyplot()
    scenes = list(summary)
    fig, axes = plt.subplots(1, len(scenes), figsize=(3.6 * len(scenes), 3.2), squeeze=False)
    x = np.arange(len(CONDITIONS))
    for ax, scene in zip(axes[0], scenes, strict=True):
        keys = list(summary[scene])
        width = 0.8 / max(1, len(keys))
        for j, key in enumerate(keys):
            nan = S.Interval(float("nan"), float("nan"), float("nan"))
            ivs = [summary[scene][key].get(c, nan) for c in CONDITIONS]
            est = np.array([100 * iv.estimate for iv in ivs])
            err = np.array([[max(0.0, e - 100 * iv.lo), max(0.0, 100 * iv.hi - e)]
                            for e, iv in zip(est, ivs, strict=True)]).T
            ax.bar(x + j * width, est, width, yerr=np.nan_to_num(err), capsize=2,
                   error_kw={"lw": 0.8}, label=short_name(rows, key))
        ax.set_xticks(x + 0.4 - width / 2, [c.replace(" ", "\n", 1) for c in CONDITIONS],
                      fontsize=7)
        ax.set_ylim(min(0.0, ax.get_ylim()[0]), 105)
        ax.set_ylabel("stick cut vs zero excitation (%)", fontsize=8)
        ax.set_title(scene, fontsize=10)
    # one legend for all panels, below them, where it covers no bar
    handles: dict[str, Any] = {}
    for ax in axes[0]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    fig.legend(list(handles.values()), list(handles), loc="lower center", fontsize=7,
               ncol=min(len(handles), 6), frameon=False)
    fig.tight_layout(rect=(0.0, 0.1 if len(handles) <= 6 else 0.16, 1.0, 1.0))
    fig.savefig(path, dpi=90)
    plt.close(fig)
