"""Say so before fricenv's kernels compile, instead of going quiet for a minute.

numba compiles a kernel on its first call and keeps the machine code in its on-disk cache
(:mod:`fricenv._numba_cache`). From an empty cache, or after any edit of the package's
source, the first call of a workload stalls for tens of seconds with nothing on the
screen. This module tells, without compiling or loading anything, whether a workload's
entry kernels are already in the cache (it reads the index file numba keeps beside each
cached function), and tells in one line when they are not: what compiles, about how
long it takes, and where the cache is.

The commands announce their workloads before they start (:mod:`fricenv.cli._notice`). A
call from Python is announced as it starts compiling: :mod:`fricenv._compile_listener`
(installed when :mod:`fricenv.jit` is imported) hears numba's ``numba:compile`` event,
which fires only on a cache miss, and :func:`compile_starting` names the workload that
compiles, once per workload and process. Where the line goes:

- ``FRICENV_QUIET=1`` in the environment: nowhere;
- if the application (or the ``fricenv`` command) has configured logging, a handler on the
  ``fricenv`` logger or the root logger: to that logger, at INFO, so that logging's
  own levels and handlers decide (``logging.getLogger("fricenv").setLevel("WARNING")``
  silences it);
- otherwise: printed to stderr, ``fricenv: compiling ...``, so that a REPL or notebook
  user sees why the first call takes tens of seconds.

The listener (:mod:`fricenv._compile_listener`) also sums the seconds spent compiling,
which :mod:`fricenv.progress` leaves out of its bars' rates.
"""

from __future__ import annotations

import contextlib
import importlib
import logging
import os
import sys
import threading
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from . import _compile_listener
from ._numba_cache import cache_dir_for

logger = logging.getLogger(__name__)

#: The environment variable that silences the notice (any value but "", "0", "false", "no").
QUIET_ENV = "FRICENV_QUIET"

#: Each workload's entry kernels (the dispatchers Python calls first, which compile
#: everything they call), per core method: ``"exact"`` (the closed form), ``"event"``,
#: ``"any"`` (both, chosen per plant at run time) or ``"rk4"``. ``"module:attribute"``
#: names, the attribute possibly dotted, resolved only when a check runs: the one place to
#: change when a kernel is renamed (a test resolves every name). ``"vector_env:parallel"``
#: is the threaded step of the vector environment, compiled only from
#: ``PARALLEL_MIN_ENVS`` environments.
ENTRY_KERNELS: dict[str, dict[str, tuple[str, ...]]] = {
    "simulate": {  # a time history (``simulate``)
        "exact": ("fricenv.core:record_exact",),
        "event": ("fricenv.core:record_event",),
        "rk4": ("fricenv.core:run_rk4",),
    },
    "run_stats": {  # statistics without a trajectory (``run_stats``)
        "exact": ("fricenv.core:advance_exact",),
        "event": ("fricenv.core:advance_event",),
    },
    "sweep": {
        "exact": ("fricenv.cell_kernels:CELL_KERNELS.exact",),
        "event": ("fricenv.cell_kernels:CELL_KERNELS.event",),
    },
    "env": {
        method: (f"fricenv.envs.steppers:{method.upper()}.step_single",
                 "fricenv.envs.kernels:start_episode")
        for method in ("exact", "event", "any")
    },
    "vector_env": {
        method: (f"fricenv.envs.steppers:{method.upper()}.step_batch",
                 "fricenv.envs.batch:start_batch")
        for method in ("exact", "event", "any")
    },
    "vector_env:parallel": {
        method: (f"fricenv.envs.steppers:{method.upper()}.step_batch_parallel",)
        for method in ("exact", "event", "any")
    },
}

#: About how long each workload's kernels take to compile from an empty cache, in seconds
#: of wall-clock time on a 2-core x86-64 machine, for the notice only: the time varies with
#: the machine, its load and what is already cached (kernels that workloads share compile
#: once). Measured by ``fricenv bench compile`` (one workload per fresh process and cache;
#: docs/performance.md, "Cold start"): a Coulomb ``simulate`` 20 s, the first step of the
#: paper scene's env 25-49 s and of the Stribeck scene's 21 s, a 16-plant vector env 24 s, a
#: 3 x 3 Coulomb map 23 s; the RK4 kernel 3 s.
COMPILE_SECONDS: dict[str, float] = {
    "simulate": 20.0,
    "run_stats": 20.0,
    "sweep": 25.0,
    "env": 25.0,
    "vector_env": 25.0,
    "vector_env:parallel": 30.0,
}
#: Where one method's kernels take far from their workload's ``COMPILE_SECONDS``.
METHOD_SECONDS: dict[tuple[str, str], float] = {("simulate", "rk4"): 5.0}

#: The ``CELL_KERNELS`` keys (core method codes) by method name.
_METHOD_CODES = {"exact": "METHOD_EXACT", "event": "METHOD_EVENT"}


def resolve(name: str) -> Any:
    """The object a ``"module:attribute.attribute"`` name of ``ENTRY_KERNELS`` stands for
    (``ImportError``/``AttributeError``/``KeyError`` if it no longer exists). A dict
    attribute takes a method name, e.g. ``CELL_KERNELS.exact``."""
    module_name, _, path = name.partition(":")
    obj: Any = importlib.import_module(module_name)
    for part in path.split("."):
        if isinstance(obj, dict):
            from . import layout

            obj = obj[getattr(layout, _METHOD_CODES[part])]
        else:
            obj = getattr(obj, part)
    return obj


def dispatcher_cached(dispatcher: Any) -> bool:
    """Whether numba's cache holds machine code of ``dispatcher`` for this process: its
    index file exists, carries the current source stamp and numba version (numba's
    ``_load_index`` returns ``{}`` otherwise), and lists an entry for this machine and this
    function's bytecode. Reads the index only: compiles and loads nothing. A function
    compiled in this process already counts as cached."""
    if getattr(dispatcher, "overloads", None):
        return True
    cache: Any = getattr(dispatcher, "_cache", None)
    cache_file = getattr(cache, "_cache_file", None)
    if cache_file is None:  # not a cached function: it compiles in every process
        return False
    try:
        index = cache_file._load_index()
    except Exception:  # an unreadable index: numba recompiles, and so says this
        return False
    if not index:
        return False
    try:
        here = cache._index_key(None, dispatcher.targetctx.codegen())[1:]
    except Exception:  # another numba's internals: an index entry is the best we know
        return True
    return any(isinstance(key, tuple) and key[1:] == here for key in index)


def missing_kernels(workload: str, method: str) -> list[str]:
    """The entry kernels of ``workload`` run by ``method`` that are not in the cache (a
    name that no longer resolves counts as missing: better a notice too many than a
    silent compile)."""
    try:
        names = ENTRY_KERNELS[workload][method]
    except KeyError:
        raise ValueError(f"no entry kernels for workload {workload!r} with method "
                         f"{method!r}; expected one of {sorted(ENTRY_KERNELS)} with its "
                         f"methods") from None
    missing = []
    for name in names:
        try:
            cached = dispatcher_cached(resolve(name))
        except (ImportError, AttributeError, KeyError):
            logger.debug("entry kernel %s not found", name)
            cached = False
        if not cached:
            missing.append(name)
    return missing


def is_cached(workload: str, method: str) -> bool:
    """Whether the first call of ``workload`` by ``method`` loads its kernels from the
    cache rather than compiling them (see :func:`dispatcher_cached`)."""
    return not missing_kernels(workload, method)


def method_for_law(law: str) -> str:
    """The core method that runs a plant of friction law ``law`` (the closed form for
    Coulomb plants away from resonance, else the event method)."""
    return "exact" if str(law).lower() == "coulomb" else "event"


def method_for_scene(scene: str) -> str:
    """The method set of the entry kernels the environments of ``scene`` run, with the
    scene's default settings: ``"exact"``, ``"event"`` or ``"any"``."""
    from .envs import kernels as K
    from .envs.setup import EnvSetup
    from .envs.steppers import steppers_for_plants

    setup = EnvSetup.build(scene)
    return steppers_for_plants(setup.kernel_cfg[K.C_METHOD], setup.scene.params.to_array(),
                               setup.draw_lo, setup.draw_hi).name


def cache_location() -> str:
    """Where numba keeps fricenv's compiled kernels: ``NUMBA_CACHE_DIR`` if set, else the
    per-user folder of this source digest (:mod:`fricenv._numba_cache`), or, where that
    cannot be written, the ``__pycache__`` folders beside the package's sources (or
    numba's per-user fallback where those are not writable)."""
    from .jit import cache_dir

    configured = cache_dir()
    if configured:
        return configured
    folder = cache_dir_for(Path(__file__).resolve().parent)
    if folder is not None:
        return os.fspath(folder)
    try:
        path = resolve(ENTRY_KERNELS["simulate"]["exact"][0])._cache.cache_path
    except Exception:
        path = str(Path(__file__).parent / "__pycache__")
    if Path(path).resolve().is_relative_to(Path(__file__).resolve().parent):
        return f"__pycache__ folders under {Path(__file__).parent}"
    return os.fspath(path)


def describe(needs: Iterable[tuple[str, str]]) -> str | None:
    """The notice for the ``(workload, method)`` pairs about to run, or None when all their
    kernels are cached."""
    cold = [(w, m) for w, m in dict.fromkeys(needs) if not is_cached(w, m)]
    if not cold:
        return None
    seconds = sum(METHOD_SECONDS.get((w, m), COMPILE_SECONDS[w]) for w, m in cold)
    what = ", ".join(f"{w} ({m})" for w, m in cold)
    return (f"compiling numba kernels for {what}: about {_duration(seconds)} on 2 cores, "
            f"once; cached in {cache_location()} (fricenv warmup compiles ahead)")


def quiet() -> bool:
    """Whether ``FRICENV_QUIET`` asks for no notice."""
    return os.environ.get(QUIET_ENV, "").strip().lower() not in ("", "0", "false", "no")


def _logging_configured() -> bool:
    """Whether a handler other than the package's ``NullHandler`` would see a record of the
    ``fricenv`` loggers (the application's ``basicConfig``, the command's stderr handler)."""
    log: logging.Logger | None = logger
    while log is not None:
        if any(not isinstance(h, logging.NullHandler) for h in log.handlers):
            return True
        if not log.propagate:
            return False
        log = log.parent
    return False


def emit(message: str) -> bool:
    """Show ``message`` as the module docstring says (logger, stderr or nowhere); whether
    it went anywhere."""
    if quiet():
        return False
    if _logging_configured():
        logger.info(message)
        return logger.isEnabledFor(logging.INFO)
    if logging.getLogger("fricenv").level > logging.INFO:  # silenced by its level alone
        return False
    print(f"fricenv: {message}", file=sys.stderr, flush=True)
    return True


def announce(needs: Iterable[tuple[str, str]]) -> bool:
    """Show :func:`describe`'s notice (:func:`emit`), if anything will compile; whether
    there was one to show. Its workloads count as announced: the compile they start adds
    no second line."""
    pairs = list(dict.fromkeys(needs))
    message = describe(pairs)
    if message is None:
        return False
    _announced.update(x for w, m in pairs for x in (w, f"{w} ({m})"))
    emit(message)
    return True


# -- the notice of calls from Python ----------------------------------------------------------
#: Workloads already announced in this process (by a command or by the listener).
_announced: set[str] = set()
_lock = threading.Lock()


def compile_starting(dispatcher: Any) -> None:
    """Announce the workload that the compile of ``dispatcher`` (a fricenv kernel, its
    outermost compile) belongs to, unless it has been (:mod:`fricenv._compile_listener`
    calls this). Once per workload and method: a workload's first compile names the
    workload (its helpers compile first, before its method is known), a later compile of
    another method's entry kernel (the event method's sweep after the closed form's)
    names that method."""
    workload, method = entry_of(dispatcher)
    if workload is None and _in_command:
        return  # (the command announced what it runs; a helper kernel adds nothing)
    if workload is None:
        caller = _api_module()
        workload = next((w for prefix, w in MODULE_WORKLOADS if caller == prefix
                         or caller.startswith(prefix + ".")), None)
        if workload is None:  # (a kernel of no known workload: named by its module)
            workload = caller or dispatcher.py_func.__module__
    pair = f"{workload} ({method})"
    with _lock:
        if method is None:
            if workload in _announced:
                return
        elif pair in _announced:
            return
        elif workload in _announced and not any(
                k.startswith(f"{workload} (") for k in _announced):
            _announced.add(pair)  # (the workload's first line covered its first method)
            return
        _announced.update((workload, pair) if method else (workload,))
    name = workload if method is None else pair
    seconds = METHOD_SECONDS.get((workload, method or ""), COMPILE_SECONDS.get(workload))
    how_long = "up to a minute" if seconds is None else f"about {_duration(seconds)}"
    emit(f"compiling numba kernels for {name}: {how_long} on 2 cores, once; cached in "
         f"{cache_location()} ({QUIET_ENV}=1 silences this; fricenv warmup compiles ahead)")


_compile_listener.on_compile = compile_starting  # (on import: ``import fricenv`` does)


#: The workload a call from Python compiles for, by the module that was called (the first
#: prefix that matches), when the first kernel that compiles is a helper rather than one of
#: ``ENTRY_KERNELS`` (``simulate`` compiles its start-state kernels first).
MODULE_WORKLOADS: tuple[tuple[str, str], ...] = (
    ("fricenv.simulate", "simulate"),
    ("fricenv.sweep", "sweep"),
    ("fricenv.cells", "sweep"),
    ("fricenv.maps", "sweep"),
    ("fricenv.envs.vector", "vector_env"),
    ("fricenv.envs.sb3", "vector_env"),
    ("fricenv.envs.batch", "vector_env"),
    ("fricenv.envs", "env"),
)

#: Whether a ``fricenv`` command runs (it announces its own workloads: :func:`in_command`).
_in_command = False


@contextlib.contextmanager
def in_command() -> Iterator[None]:
    """While a ``fricenv`` command runs: the listener announces only entry kernels the
    command's own notice did not name."""
    global _in_command
    before, _in_command = _in_command, True
    try:
        yield
    finally:
        _in_command = before


def entry_of(dispatcher: Any) -> tuple[str | None, str | None]:
    """``(workload, method)`` of which ``dispatcher`` is an entry kernel; the method is
    None for a kernel that several methods share, and both for a kernel of no workload.
    Modules not imported yet are not imported for this: none of their kernels is the one
    compiling."""
    owner: str | None = None
    hits: list[str] = []
    for workload, methods in ENTRY_KERNELS.items():
        for method, names in methods.items():
            for name in names:
                if name.partition(":")[0] not in sys.modules:
                    continue
                try:
                    hit = resolve(name) is dispatcher
                except (ImportError, AttributeError, KeyError):
                    continue
                if hit and owner in (None, workload):
                    owner = workload
                    hits.append(method)
    return owner, hits[0] if len(hits) == 1 else None


def _api_module() -> str:
    """The module of the outermost fricenv frame on this thread's stack: the fricenv call
    the application made ("" if none)."""
    frame: Any = sys._getframe(1)
    outer = ""
    while frame is not None:
        module = frame.f_globals.get("__name__", "")
        if module == "fricenv" or module.startswith("fricenv."):
            outer = module
        frame = frame.f_back
    return outer


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min"
