"""Compile fricenv's kernels for chosen workloads before they are needed.

numba compiles a kernel on its first call, and stores the machine code in its on-disk cache
(a per-user folder of the package's source digest, or ``NUMBA_CACHE_DIR``), keyed on the
whole package's source (:mod:`fricenv._numba_cache`). Every process that finds a kernel
there loads it in a fraction of the time compiling takes. :func:`warmup` runs each chosen
workload once on a tiny problem, so that the cache holds its kernels: call it once, in the
parent, before starting worker processes (``SubprocVecEnv``, a process pool, a cluster's
workers on the same file system), and the workers load instead of each compiling the same
kernels.

The work splits into independent parts (:func:`parts`): one per friction law and workload,
one per scene and environment workload. ``fricenv warmup --jobs N`` runs them in N
processes at once, each compiling into the shared cache (numba writes each cache file to a
temporary name and renames it, so concurrent writers are safe).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import NamedTuple

from . import compile_notice
from ._numba_cache import source_digest
from .checks import check_bool, got
from .params import FRICTION_LAWS, OscillatorParams

#: What :func:`warmup` can prepare.
WORKLOADS = ("simulate", "sweep", "env", "vector_env")
#: The workloads whose parts are per scene (the others are per friction law).
SCENE_WORKLOADS = ("env", "vector_env")


class Part(NamedTuple):
    """One independent piece of a warm-up: a workload for one friction law (``simulate``,
    ``sweep``) or one scene (``env``, ``vector_env``)."""

    workload: str
    target: str
    """The friction law or the scene."""

    @property
    def name(self) -> str:
        """``workload:target``, the key of :func:`warmup`'s result."""
        return f"{self.workload}:{self.target}"


def cache_digest() -> str:
    """The digest of the package's source that stamps every cached kernel (see
    :mod:`fricenv._numba_cache`): a cache saved under this key holds kernels for exactly
    this source, so CI can key a saved ``NUMBA_CACHE_DIR`` on it."""
    return source_digest(Path(__file__).resolve().parent)


def _default_scenes() -> list[str]:
    from .envs import ENV_IDS

    return list(ENV_IDS.values())


def _names(what: str, names: object) -> list:
    """``names`` as a list: a single str is one name, not its letters; anything else
    must be an iterable of names (``TypeError`` naming ``what`` otherwise)."""
    if isinstance(names, str):
        return [names]
    if not isinstance(names, Iterable):
        raise TypeError(f"{what} must be a name or an iterable of names, {got(names)}")
    return list(names)


def parts(laws: Iterable[str] = ("coulomb",), workloads: Iterable[str] = WORKLOADS,
          scenes: Iterable[str] | None = None) -> list[Part]:
    """The parts :func:`warmup` runs for these arguments, in its order; ``ValueError``
    naming an unknown law, workload or scene before anything runs. A single name is taken
    as one (``laws="coulomb"`` ran the law names ``'c'``, ``'o'``, ... one letter each)."""
    laws = [str(law).lower() for law in _names("laws", laws)]
    for law in laws:
        if law not in FRICTION_LAWS:
            raise ValueError(f"unknown friction law {law!r}; expected some of "
                             f"{sorted(FRICTION_LAWS)}")
    workloads = _names("workloads", workloads)
    for w in workloads:
        if w not in WORKLOADS:
            raise ValueError(f"unknown workload {w!r}; expected some of {WORKLOADS}")
    out = [Part(w, law) for law in laws for w in ("simulate", "sweep") if w in workloads]
    if any(w in workloads for w in SCENE_WORKLOADS):
        from .envs.scenes import SCENES

        chosen = (_default_scenes() if scenes is None
                  else [str(s) for s in _names("scenes", scenes)])
        for scene in chosen:
            if scene not in SCENES:
                raise ValueError(f"unknown scene {scene!r}; expected some of "
                                 f"{sorted(SCENES)}")
        out += [Part(w, scene) for scene in chosen for w in SCENE_WORKLOADS
                if w in workloads]
    return out


def needs(part: Part, parallel: bool = True) -> list[tuple[str, str]]:
    """The ``(workload, method)`` pairs of :mod:`fricenv.compile_notice` whose entry
    kernels ``part`` runs."""
    if part.workload in SCENE_WORKLOADS:
        method = compile_notice.method_for_scene(part.target)
        pairs = [(part.workload, method)]
        if part.workload == "vector_env" and parallel:
            pairs.append(("vector_env:parallel", method))
        return pairs
    method = compile_notice.method_for_law(part.target)
    if part.workload == "simulate":
        return [("simulate", method), ("run_stats", method)]
    return [(part.workload, method)]


def is_cached(part: Part, parallel: bool = True) -> bool:
    """Whether ``part``'s kernels are all in numba's cache already (nothing compiles)."""
    return all(compile_notice.is_cached(w, m) for w, m in needs(part, parallel))


def run_part(part: Part, parallel: bool = True) -> float:
    """Run ``part`` once on a tiny problem (compiling or loading its kernels); the seconds
    it took. A module-level function, so that worker processes can run it."""
    start = time.perf_counter()
    _RUNNERS[part.workload](part.target, parallel)
    return time.perf_counter() - start


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
    When something will compile, says so first on the ``fricenv`` logger (INFO).
    """
    parallel = check_bool("parallel", parallel)  # ('no' is a true value)
    todo = parts(laws, workloads, scenes)
    compile_notice.announce(pair for part in todo for pair in needs(part, parallel))
    return {part.name: run_part(part, parallel) for part in todo}


def _simulate(law: str, parallel: bool) -> None:
    """``simulate`` and ``run_stats`` (the workloads import what they run, so that
    ``fricenv warmup --help`` and the part list load no kernels)."""
    from .simulate import run_stats, simulate

    p = OscillatorParams.preset(law, u0=1.0, nu=0.5)
    simulate(p, 1.0, dt_out=0.5)
    run_stats(p, 1.0)


def _sweep(law: str, parallel: bool) -> None:
    from .sweep import cell_statistics

    p = OscillatorParams.preset(law, u0=1.0, nu=0.5)
    cell_statistics([p], transient_min=1.0, window_min=1.0, q_max=0, n_strobe=2)


def _env(scene: str, parallel: bool) -> None:
    """One step of the scene's single environment (imported here: the simulator alone
    needs no Gymnasium)."""
    from .envs.stick_slip import StickSlipEnv

    env = StickSlipEnv(scene=scene)
    env.reset(seed=0)
    env.step(env.action_space.sample() * 0.0)


def _vector_env(scene: str, parallel: bool) -> None:
    """One step of the scene's vector environment, and with ``parallel`` of one large
    enough to run its threaded kernel."""
    from .envs.vector import PARALLEL_MIN_ENVS, StickSlipVectorEnv

    for n in [1, PARALLEL_MIN_ENVS] if parallel else [1]:
        vec = StickSlipVectorEnv(num_envs=n, scene=scene)
        vec.reset(seed=0)
        vec.step(vec.action_space.sample() * 0.0)


_RUNNERS: dict[str, Callable[[str, bool], None]] = {
    "simulate": _simulate, "sweep": _sweep, "env": _env, "vector_env": _vector_env}
