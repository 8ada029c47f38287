"""The control benchmark's scenes in worker processes (``--jobs``).

Each scene is scored in a fresh, spawned process; its entries come back without their
controllers (models and closures do not pickle), which the page does not need.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from .benchmark_rows import SCENE_COST, Row, evaluate_scene
from .rollouts import Controller
from .scoring import Entry


def _evaluated_elsewhere(k: int) -> Controller:
    raise RuntimeError("this entry was evaluated in a worker process; its scores travel, "
                       "its controllers do not")


def _portable(entries: dict[str, Entry]) -> dict[str, Entry]:
    """``entries`` with their controllers replaced by a stand-in (models and closures do
    not pickle; the scores, info and the number of models do)."""
    for e in entries.values():
        e.factories = [_evaluated_elsewhere] * len(e.factories)
    return entries


def _scene_in_worker(scene: str, args: argparse.Namespace
                     ) -> tuple[dict[str, Entry], dict[str, dict[str, Entry]]]:
    res, gen = evaluate_scene(scene, args)
    return _portable(res), {c: _portable(es) for c, es in gen.items()}


def map_scenes(args: argparse.Namespace, rows: Sequence[Row]) -> list[tuple[Any, Any]]:
    """``evaluate_scene`` of every scene, ``--jobs`` of them at a time in fresh worker
    processes (spawned, not forked: numba's thread pools do not survive a fork), each
    with an equal share of the numba threads."""
    if args.jobs == 1 or len(args.scenes) == 1:
        return [evaluate_scene(scene, args, rows) for scene in args.scenes]
    import multiprocessing as mp
    import os
    from concurrent.futures import ProcessPoolExecutor

    jobs = min(args.jobs, len(args.scenes))
    threads = str(max(1, (os.cpu_count() or 1) // jobs))
    old = os.environ.get("NUMBA_NUM_THREADS")
    os.environ["NUMBA_NUM_THREADS"] = threads  # (read by the workers at their numba import)
    try:
        with ProcessPoolExecutor(jobs, mp_context=mp.get_context("spawn")) as pool:
            # the costliest scenes first, so that no worker is left with one at the end
            first = sorted(args.scenes, key=lambda sc: -SCENE_COST.get(sc, 1.0))
            futures = {sc: pool.submit(_scene_in_worker, sc, args) for sc in first}
            return [futures[sc].result() for sc in args.scenes]
    finally:
        if old is None:
            os.environ.pop("NUMBA_NUM_THREADS", None)
        else:
            os.environ["NUMBA_NUM_THREADS"] = old
