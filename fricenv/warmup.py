"""Compile fricenv's kernels for chosen workloads before they are needed.

numba compiles a kernel on its first call, and stores the machine code in its on-disk cache
(``__pycache__`` beside the sources, or ``NUMBA_CACHE_DIR``), keyed on the whole package's
source (:mod:`fricenv._numba_cache`). Every process that finds a kernel there loads it in a
fraction of the time compiling takes. :func:`warmup` runs each chosen workload once on a
tiny problem, so that the cache holds its kernels: call it once, in the parent, before
starting worker processes (``SubprocVecEnv``, a process pool, a cluster's workers on the
same file system), and the workers load instead of each compiling the same kernels.
"""

from __future__ import annotations

import time
from collections.abc import Iterable

from .params import FRICTION_LAWS, OscillatorParams
from .simulate import run_stats, simulate
from .sweep import cell_statistics

#: What :func:`warmup` can prepare.
WORKLOADS = ("simulate", "sweep", "env", "vector_env")


def warmup(laws: Iterable[str] = ("coulomb",), workloads: Iterable[str] = WORKLOADS,
           scenes: Iterable[str] | None = None, parallel: bool = True) -> dict[str, float]:
    """Compile (or load from numba's cache) the kernels of the chosen workloads.

    ``laws``: friction laws (``FRICTION_LAWS``); the Coulomb law runs the closed form, the
    others the event method, and each method's kernels are compiled separately.
    ``workloads``: any of ``"simulate"`` (``simulate`` and ``run_stats``), ``"sweep"``
    (``regime_map``, ``cell_statistics``), ``"env"`` (one step of the single environment of
    each scene) and ``"vector_env"`` (one step of the native vector environment, and with
    ``parallel`` its threaded kernel too). ``scenes``: the environments' scenes (default:
    every registered one). Returns the seconds each part took: seconds to minutes each from
    an empty cache, milliseconds once cached. Results of later calls do not depend on it.
    """
    laws = [str(law).lower() for law in laws]
    for law in laws:
        if law not in FRICTION_LAWS:
            raise ValueError(f"unknown friction law {law!r}; expected some of "
                             f"{sorted(FRICTION_LAWS)}")
    workloads = list(workloads)
    for w in workloads:
        if w not in WORKLOADS:
            raise ValueError(f"unknown workload {w!r}; expected some of {WORKLOADS}")
    took: dict[str, float] = {}

    def timed(name: str, run) -> None:
        start = time.perf_counter()
        run()
        took[name] = time.perf_counter() - start

    for law in laws:
        p = OscillatorParams.preset(law, u0=1.0, nu=0.5)
        if "simulate" in workloads:
            timed(f"simulate:{law}", lambda p=p: (simulate(p, 1.0, dt_out=0.5),
                                                  run_stats(p, 1.0)))
        if "sweep" in workloads:
            timed(f"sweep:{law}", lambda p=p: cell_statistics(
                [p], transient_min=1.0, window_min=1.0, n_strobe=2))
    if "env" in workloads or "vector_env" in workloads:
        _warm_envs(workloads, scenes, parallel, timed)
    return took


def _warm_envs(workloads: list[str], scenes: Iterable[str] | None, parallel: bool,
               timed) -> None:
    """One step of each scene's environments (imported here: the simulator alone needs
    no Gymnasium)."""
    from .envs import ENV_IDS
    from .envs.stick_slip import StickSlipEnv
    from .envs.vector import PARALLEL_MIN_ENVS, StickSlipVectorEnv

    for scene in (list(ENV_IDS.values()) if scenes is None else list(scenes)):
        if "env" in workloads:
            def single(scene=scene) -> None:
                env = StickSlipEnv(scene=scene)
                env.reset(seed=0)
                env.step(env.action_space.sample() * 0.0)
            timed(f"env:{scene}", single)
        if "vector_env" in workloads:
            sizes = [1, PARALLEL_MIN_ENVS] if parallel else [1]

            def vector(scene=scene, sizes=sizes) -> None:
                for n in sizes:
                    vec = StickSlipVectorEnv(num_envs=n, scene=scene)
                    vec.reset(seed=0)
                    vec.step(vec.action_space.sample() * 0.0)
            timed(f"vector_env:{scene}", vector)
