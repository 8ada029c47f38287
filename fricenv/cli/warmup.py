"""``fricenv warmup``: compile the kernels of chosen workloads into numba's on-disk cache.

Run it once after installing or upgrading fricenv, in CI before the tests, or in a parent
process before starting workers (``SubprocVecEnv``, a Dask cluster on the same file
system): later processes then load the kernels instead of each compiling them. Example::

    fricenv warmup --laws coulomb stribeck --workloads simulate sweep --jobs 2
    fricenv warmup --print-digest     # the source digest the cache is keyed on
"""

from __future__ import annotations

import argparse
import importlib
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed

from fricenv.params import FRICTION_LAWS
from fricenv.warmup import WORKLOADS, Part, cache_digest, is_cached, needs, parts


def _run_part(part: Part, parallel: bool) -> float:
    """``fricenv.warmup.run_part``, looked up when called (``fricenv.warmup`` the attribute
    is the function of that name)."""
    run: Callable[[Part, bool], float] = importlib.import_module("fricenv.warmup").run_part
    return run(part, parallel)


def jobs(text: str) -> int:
    """A positive whole number of worker processes."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text!r}")
    return n


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    from fricenv.cli._args import parser
    from fricenv.envs import HORIZONS as SCENES  # (the scenes' names, without their kernels)

    p = parser(prog, "Compile the kernels of chosen workloads into numba's on-disk cache, "
                     "so that later processes load them.",
               ["fricenv warmup --laws coulomb stribeck --workloads simulate sweep --jobs 2",
                "fricenv warmup --print-digest"])
    p.add_argument("--laws", nargs="+", default=["coulomb"], choices=sorted(FRICTION_LAWS),
                   metavar="LAW", help=f"friction laws, of {', '.join(sorted(FRICTION_LAWS))}")
    p.add_argument("--workloads", nargs="+", default=list(WORKLOADS),
                   choices=WORKLOADS, metavar="WORKLOAD",
                   help=f"workloads, of {', '.join(WORKLOADS)}")
    p.add_argument("--scenes", nargs="+", default=None, choices=sorted(SCENES),
                   metavar="SCENE", help="the environments' scenes, of "
                   f"{', '.join(sorted(SCENES))} (default: the registered environments')")
    p.add_argument("--jobs", type=jobs, default=1, metavar="N",
                   help="run up to N parts at once, each in a process of its own")
    p.add_argument("--no-parallel", action="store_true",
                   help="skip the vector environment's threaded kernel")
    p.add_argument("--quiet", action="store_true", help="no notice, progress bar or table")
    p.add_argument("--print-digest", action="store_true",
                   help="print the source digest that keys the cache, compile nothing")
    return p


def _in_process(todo: list[Part], parallel: bool) -> Iterator[tuple[str, float]]:
    for part in todo:
        yield part.name, _run_part(part, parallel)


def _in_workers(todo: list[Part], parallel: bool,
                n_jobs: int) -> Iterator[tuple[str, float]]:
    """Each part in a worker process, up to ``n_jobs`` at once. ``spawn``: a fresh
    interpreter, whatever threads or numba threading layer this process has started."""
    context = multiprocessing.get_context("spawn")
    run = importlib.import_module("fricenv.warmup").run_part  # (what the workers import)
    with ProcessPoolExecutor(max_workers=min(n_jobs, len(todo)), mp_context=context,
                             initializer=_quiet_worker) as pool:
        futures: dict[Future[float], str] = {
            pool.submit(run, part, parallel): part.name for part in todo}
        for future in as_completed(futures):
            yield futures[future], future.result()


def _quiet_worker() -> None:
    """A worker's compile adds no notice of its own: this process announced them all."""
    from fricenv.compile_notice import QUIET_ENV

    os.environ[QUIET_ENV] = "1"


def table(took: dict[str, float], cached: dict[str, bool], wall: float) -> str:
    """The seconds per part, in the parts' order, whether its kernels were loaded from the
    cache or compiled, their sum and the wall-clock time of the whole run."""
    width = max(len("wall clock"), *map(len, took))
    lines = [f"{'part':<{width}}  {'seconds':>8}  kernels"]
    lines += [f"{name:<{width}}  {seconds:8.1f}  {'loaded' if cached[name] else 'compiled'}"
              for name, seconds in took.items()]
    lines.append(f"{'total':<{width}}  {sum(took.values()):8.1f}")
    lines.append(f"{'wall clock':<{width}}  {wall:8.1f}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    parser = build_parser(prog)
    args = parser.parse_args(argv)
    if args.print_digest:
        print(cache_digest())
        return 0
    parallel = not args.no_parallel
    try:
        todo = parts(args.laws, args.workloads, args.scenes)
    except (TypeError, ValueError) as e:
        parser.error(str(e))
    cached = {part.name: is_cached(part, parallel) for part in todo}
    from fricenv import compile_notice

    compile_notice.announce(pair for part in todo for pair in needs(part, parallel))
    runs = (_in_process(todo, parallel) if args.jobs == 1
            else _in_workers(todo, parallel, args.jobs))
    took: dict[str, float] = {}
    start = time.perf_counter()
    from tqdm.auto import tqdm

    with tqdm(total=len(todo), disable=args.quiet, unit="part", file=sys.stderr,
              desc="warmup") as bar:
        for name, seconds in runs:
            took[name] = seconds
            bar.set_postfix_str(f"{name} {seconds:.1f} s")
            bar.update()
    if not args.quiet:
        print(table({p.name: took[p.name] for p in todo}, cached,
                    time.perf_counter() - start))
        print(f"numba cache: {compile_notice.cache_location()}")
    return 0
