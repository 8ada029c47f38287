#!/usr/bin/env python
"""Benchmark of regime atlases (fricenv.atlas); every ratio from contenders run side by side
in one run, in alternating rounds, each warmed up first.

1. Dask's overhead: a 200 x 200 Stribeck panel (Fig. 10, eta = 3/5) on a LocalCluster of
   2 workers x 1 thread (spawn-started, kernels warmed, cluster start excluded) against the
   local threaded path (``client=None``, numba's threads) and ``regime_map``, all on the
   same cores; the results are checked bit for bit. Wall time and CPU time (this process,
   the workers and the scheduler) are both reported: on a shared machine the wall times
   of one contender moved by 2x between rounds, the CPU times far less.
2. A Coulomb atlas of 200 x 200 x 50 (u0 x nu x eta, 2e6 cells) written to Zarr: its time,
   cells per second, and the client's peak memory (resident set, sampled every 20 ms, above
   its level before the call; and the peak of Python/numpy allocations by tracemalloc in a
   tenth-size run), against the same atlas at a tenth of the eta values: the peak must not
   grow with the number of cells.
3. Cells per second per core of each friction law (one thread, 100 x 100 panels at
   eta = 3/5, u0 from 0.1 to 1000, nu from 0.02 to 4).

Usage: ``python scripts/bench_atlas.py [--rounds N] [--skip-big] [--big-dask]
[--json PATH]``. Timings depend on the machine's load; never assert on them in tests.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
import threading
import time
import tracemalloc
from pathlib import Path

import numba
import numpy as np

import fricenv
from fricenv.atlas import regime_map_dataset
from fricenv.params import OscillatorParams

#: Grids: u0 geometric over the Fig. 10 (eta = 3/5) range, nu uniform with integers on it.
PANEL_U0 = np.geomspace(0.1, 1000.0, 200)
PANEL_NU = 0.02 * np.arange(1, 201)
BIG_ETA = np.geomspace(1 / 9, 7 / 3, 50)
LAW_GRID = (np.geomspace(0.1, 1000.0, 100), 0.04 * np.arange(1, 101))
#: RSS sampling period of the memory watcher, seconds.
SAMPLE_S = 0.02


class PeakRSS:
    """Highest resident set size of this process while the block runs, above its start."""

    def __enter__(self) -> PeakRSS:
        self.start = self.peak = _rss()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)
        self._thread.start()
        return self

    def _watch(self) -> None:
        while not self._stop.wait(SAMPLE_S):
            self.peak = max(self.peak, _rss())

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, _rss())

    @property
    def growth_mb(self) -> float:
        return (self.peak - self.start) / 1e6


def _rss() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096


def _timed(fn) -> tuple[float, object]:
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def _cpu_of_process() -> float:
    import resource

    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime


def _cpu_seconds(client) -> float:
    """CPU time used so far by this process, the workers and the scheduler: the work of
    each path whatever else loads the machine (wall time alone moved by 2x between runs
    on a shared machine)."""
    workers = client.run(_cpu_of_process)
    return _cpu_of_process() + sum(workers.values()) + client.run_on_scheduler(
        _cpu_of_process)


def dask_overhead(client, rounds: int) -> dict:
    base = OscillatorParams.preset("stribeck", eta=3 / 5)
    axes = {"u0": PANEL_U0, "nu": PANEL_NU}
    contenders = {
        "local": lambda: fricenv.atlas(base, axes, progress=False),
        "dask": lambda: fricenv.atlas(base, axes, client=client, progress=False),
        "regime_map": lambda: fricenv.regime_map(base, PANEL_U0, PANEL_NU, progress=False),
    }
    small = {"u0": PANEL_U0[::20], "nu": PANEL_NU[::20]}  # warm-up: both methods' kernels
    fricenv.atlas(base, small, progress=False)
    fricenv.atlas(base, small, client=client, progress=False)
    times: dict[str, list[float]] = {k: [] for k in contenders}
    cpu: dict[str, list[float]] = {k: [] for k in contenders}
    results = {}
    for r in range(rounds):
        order = list(contenders) if r % 2 == 0 else list(contenders)[::-1]
        for name in order:
            c0 = _cpu_seconds(client)
            dt, results[name] = _timed(contenders[name])
            cpu[name].append(_cpu_seconds(client) - c0)
            times[name].append(dt)
            print(f"  round {r + 1} {name}: {dt:.2f} s wall, {cpu[name][-1]:.2f} s CPU",
                  flush=True)
    rss = client.run(lambda: __import__("psutil").Process().memory_info().rss)
    same = results["dask"].identical(results["local"])
    ref = regime_map_dataset(results["regime_map"])
    same_map = results["local"].identical(ref)
    med = {k: statistics.median(v) for k, v in times.items()}
    ratios = [d / loc for d, loc in zip(times["dask"], times["local"], strict=True)]
    return {"median_s": med, "times_s": times, "dask_over_local": med["dask"] / med["local"],
            "median_round_ratio": statistics.median(ratios),
            "dask_over_local_per_round": ratios,
            "dask_over_regime_map": med["dask"] / med["regime_map"],
            "cpu_s": cpu, "cpu_dask_over_local": statistics.median(cpu["dask"])
            / statistics.median(cpu["local"]),
            "worker_rss_mb": sorted(v / 1e6 for v in rss.values()),
            "bit_identical_dask_local": bool(same), "bit_identical_local_regime_map":
            bool(same_map), "cells": PANEL_U0.size * PANEL_NU.size}


def big_atlas(client, tmp: Path) -> dict:
    """The 2e6-cell Coulomb atlas to Zarr, and a tenth of it, each with its memory peak."""
    out = {}
    for label, eta in (("tenth", BIG_ETA[::10]), ("full", BIG_ETA)):
        axes = {"u0": PANEL_U0, "nu": PANEL_NU, "eta": eta}
        path = tmp / f"coulomb_{label}.zarr"
        with PeakRSS() as mem:
            dt, ds = _timed(lambda a=axes, p=path: fricenv.atlas(
                "coulomb", a, path=p, client=client, progress=False))
        n = int(np.prod(list(ds.sizes.values())))
        assert int((ds.label == -1).sum()) == 0
        size = sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
        out[label] = {"cells": n, "seconds": dt, "cells_per_s": n / dt,
                      "client_rss_growth_mb": mem.growth_mb, "store_mb": size / 1e6}
        print(f"  {label}: {n} cells in {dt:.1f} s ({n / dt:.0f} cells/s), client RSS "
              f"+{mem.growth_mb:.1f} MB, store {size / 1e6:.1f} MB", flush=True)
        shutil.rmtree(path)
    axes = {"u0": PANEL_U0, "nu": PANEL_NU, "eta": BIG_ETA[::10]}
    tracemalloc.start()
    try:
        fricenv.atlas("coulomb", axes, path=tmp / "traced.zarr", client=client,
                      progress=False)
        out["tenth_tracemalloc_peak_mb"] = tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()
    shutil.rmtree(tmp / "traced.zarr")
    # the variables in memory would take 44 bytes a cell
    out["full_in_memory_mb"] = 44 * out["full"]["cells"] / 1e6
    return out


def per_law() -> dict:
    out = {}
    old = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        for law in ("coulomb", "viscous", "stribeck"):
            base = OscillatorParams.preset(law, eta=3 / 5)
            axes = {"u0": LAW_GRID[0], "nu": LAW_GRID[1]}
            fricenv.atlas(base, {"u0": axes["u0"][::25], "nu": axes["nu"][::25]},
                          progress=False)
            dt, _ = _timed(lambda b=base, a=axes: fricenv.atlas(b, a, progress=False))
            out[law] = 10_000 / dt
            print(f"  {law}: {out[law]:.0f} cells/s on one core", flush=True)
    finally:
        numba.set_num_threads(old)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--skip-big", action="store_true", help="skip the 2e6-cell atlas")
    ap.add_argument("--big-dask", action="store_true",
                    help="run the 2e6-cell atlas on the cluster (default: local threads)")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    from distributed import Client, LocalCluster

    report: dict = {"numba_threads": numba.get_num_threads()}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        print("1. Dask overhead, 200 x 200 Stribeck panel (eta = 3/5)", flush=True)
        report["dask_overhead"] = d = dask_overhead(client, args.rounds)
        print(f"   medians: local {d['median_s']['local']:.2f} s, dask "
              f"{d['median_s']['dask']:.2f} s, regime_map {d['median_s']['regime_map']:.2f}"
              f" s; dask / local = {d['dask_over_local']:.3f} (rounds: "
              f"{', '.join(f'{r:.3f}' for r in d['dask_over_local_per_round'])}; median "
              f"{d['median_round_ratio']:.3f}); CPU time dask / local = "
              f"{d['cpu_dask_over_local']:.3f}; worker RSS "
              f"{', '.join(f'{m:.0f}' for m in d['worker_rss_mb'])} MB; "
              f"bit-identical: {d['bit_identical_dask_local']}, regime_map: "
              f"{d['bit_identical_local_regime_map']}", flush=True)
        if not args.skip_big:
            print("2. Coulomb atlas 200 x 200 x 50 to Zarr "
                  f"({'dask' if args.big_dask else 'local threads'})", flush=True)
            with tempfile.TemporaryDirectory() as tmp:
                report["big_atlas"] = b = big_atlas(client if args.big_dask else None,
                                                    Path(tmp))
            print(f"   client RSS growth: {b['tenth']['client_rss_growth_mb']:.1f} MB "
                  f"(2e5 cells), {b['full']['client_rss_growth_mb']:.1f} MB (2e6 cells; "
                  f"{b['full_in_memory_mb']:.0f} MB in memory); tracemalloc peak "
                  f"{b['tenth_tracemalloc_peak_mb']:.1f} MB", flush=True)
    print("3. cells per second per core, 100 x 100 panels, eta = 3/5", flush=True)
    report["cells_per_s_per_core"] = per_law()
    if args.json:
        args.json.write_text(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
