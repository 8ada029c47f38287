"""The one decorator of fricenv's numba kernels.

Every kernel is cached on disk (``cache=True``; the cache is keyed on the whole package's
source, see :mod:`fricenv._numba_cache`) and uses numba's ``error_model="numpy"``: a float
division by zero gives an inf or a NaN, as in numpy, instead of raising ZeroDivisionError
from deep inside a kernel. Subnormal data can make a Halley or Newton denominator exactly
0; the root searches then fall back to the secant point or to bisection, and a non-finite
state ends a run with STATUS_NONFINITE. It also spares the zero test before every
division.

Kernels that never allocate are compiled with ``_nrt=False`` (numba's CPU target option
that turns its reference-counting runtime off for that function; numba does not document
it, which is why it is spelled out here only). Otherwise every call that passes an array
(or a view such as P[i]) does atomic incref/decref pairs on the array's shared counter:
measured, that is ~40 % of a scan step, and with threads the counters of a batch's common
parent array bounce between cores. The caller keeps every array alive for the duration of
the call, so no count is needed. A kernel that allocates (``np.empty``, ``.copy()``) says so
with ``allocates=True`` and keeps the runtime.

Kernels are compiled one by one, and LLVM inlines small callees where it pays. numba's
IR-level inlining (``inline="always"``) is kept for two cases:

- a generic body that takes another kernel as an argument (``takes_kernels``, as in
  ``step_single_with(advance_ws, ...)``). Compiled on its own, such a function holds the
  kernel it was passed as a run-time address, which numba's cache refuses ("uses dynamic
  globals"): every process would compile it again. Inlined at the IR level into its small
  named callers (``step_single_exact``), the passed kernel becomes a plain call that
  caches;
- a body with a single call site, inside a step loop (``called_once``): typed once either
  way, so inlining it there costs no compile time.

Everywhere else IR inlining only multiplies compile time and memory: numba types the
inlined body anew at every call site.

``fastmath`` flags decide the machine code, and with it the last bit of a result, so only
sums whose order does not matter may carry them.

Threading layer
---------------
The parallel kernels (sweeps, ``cell_statistics``, the vector environment from
``envs.vector.PARALLEL_MIN_ENVS`` plants, batch rollouts) run on numba's threading layer,
which numba picks when the first of them starts. Its default here is GNU OpenMP, which is not
fork-safe: after any parallel kernel has run, a ``multiprocessing`` pool,
``ProcessPoolExecutor`` or joblib's multiprocessing backend started by ``fork`` prints
``fork() called from a process already using GNU OpenMP`` and its workers hang or crash.
This module therefore asks numba for the ``"safe"`` layer, Intel TBB (a dependency where
its wheels exist): safe after ``fork`` and safe to call from several Python threads at once
(Dask workers with several threads, a thread per environment).

The ``tbb`` wheel installs ``libtbb`` where the dynamic loader does not look, so
:mod:`fricenv._tbb` loads it by its absolute path before numba looks for it (``import
fricenv`` does so too, without importing numba).

Where TBB still cannot be loaded (no wheel for the platform) it asks for ``"forksafe"``,
which on GNU OpenMP systems is numba's ``workqueue`` layer: fork-safe too, but it aborts
the process when parallel kernels run from two Python threads at the same time. Every
Python call of a parallel kernel therefore runs inside :func:`parallel_section`, which
does nothing on a thread-safe layer (TBB, OpenMP) and otherwise takes one process-wide
lock, so that such calls run one after another. A ``NUMBA_THREADING_LAYER`` set in the
environment is left as it is (the lock then follows the layer it gives).
:func:`threading_info` says which layer runs, where TBB came from and whether calls are
serialised.
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import os
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ._tbb import TBB_LIBRARY as TBB_LIBRARY
from ._tbb import preload as preload_tbb

#: The layers on which parallel kernels may run from several Python threads at once
#: (numba's threading-layer documentation); on any other, calls are serialised.
THREAD_SAFE_LAYERS = ("tbb", "omp")


def _tbb_loads() -> bool:
    """Whether numba's TBB threading layer can be loaded: the ``tbb`` wheel is installed,
    its library is loaded or the loader finds it, and numba accepts its version. Asked the
    way numba asks when it starts a layer (its version check loads the library, then its
    TBB pool)."""
    try:
        from numba.np.ufunc.parallel import _check_tbb_version_compatible

        _check_tbb_version_compatible()
        importlib.import_module("numba.np.ufunc.tbbpool")
    except (ImportError, OSError):
        return False
    return True


# On import, in this order: TBB is loaded before numba is imported here (numba itself
# looks for it only when it starts a threading layer), numba's cache is keyed on the
# package's source before any kernel is decorated (every kernel passes through ``kernel``
# below), the compile notice listens before any kernel can compile, and the threading
# layer is chosen before any parallel kernel can run. Every fricenv module that imports
# numba imports this module at its top as well (tests/test_import_graph.py); ``import
# fricenv`` imports neither.
TBB_PATH = preload_tbb()

import numba  # noqa: E402
from numba import njit  # noqa: E402
from numba.core import event, types  # noqa: E402

from . import _compile_listener, _numba_cache  # noqa: E402

_numba_cache.install(Path(__file__).parent)
_compile_listener.listen(event)  # a call from Python that compiles says so (fricenv.compile_notice)
TBB_LOADS = _tbb_loads()


def choose_threading_layer() -> str:
    """Ask numba for a fork-safe threading layer (see the module docstring) unless the user
    chose one with ``NUMBA_THREADING_LAYER``; the layer asked for. It takes effect if no
    parallel kernel has run yet in this process."""
    config: Any = numba.config  # (numba sets its options as module attributes at run time)
    if os.environ.get("NUMBA_THREADING_LAYER"):
        return str(config.THREADING_LAYER)
    config.THREADING_LAYER = "safe" if TBB_LOADS else "forksafe"
    return str(config.THREADING_LAYER)


THREADING_LAYER = choose_threading_layer()  # on import, before any kernel can run

_NO_LOCK = contextlib.nullcontext()
#: Held around every parallel kernel call when the layer is not thread-safe. Reentrant, so
#: that a caller may hold it around a call that takes it again.
_PARALLEL_LOCK = threading.RLock()
_section: contextlib.AbstractContextManager[Any] | None = None  # decided at the first call
_decide_lock = threading.Lock()


def _decide_section() -> contextlib.AbstractContextManager[Any]:
    """Start numba's threading layer (as the first parallel kernel would) and pick what
    :func:`parallel_section` returns from the layer it gave."""
    global _section
    with _decide_lock:
        if _section is None:
            numba.get_num_threads()  # (launches the layer if no parallel kernel has yet)
            layer = numba.threading_layer()
            _section = _NO_LOCK if layer in THREAD_SAFE_LAYERS else _PARALLEL_LOCK
        return _section


def _new_locks_in_child() -> None:
    """After ``fork``: fresh locks, since a thread of the parent that held one (inside a
    parallel kernel) does not exist in the child, which would wait for it for ever."""
    global _PARALLEL_LOCK, _section, _decide_lock
    serialised = _section is _PARALLEL_LOCK
    _PARALLEL_LOCK = threading.RLock()
    _decide_lock = threading.Lock()
    if serialised:
        _section = _PARALLEL_LOCK


if hasattr(os, "register_at_fork"):  # (not on Windows, which has no fork)
    os.register_at_fork(after_in_child=_new_locks_in_child)


def parallel_section(parallel: bool = True) -> contextlib.AbstractContextManager[Any]:
    """The context every Python call of a parallel kernel runs in: on a thread-safe layer
    nothing, else the process-wide lock that keeps two threads from entering parallel
    kernels at once (see the module docstring). ``parallel=False`` (a serial kernel chosen
    at run time) needs no lock. Use as ``with parallel_section(): kernel(...)``."""
    if not parallel:
        return _NO_LOCK
    return _section if _section is not None else _decide_section()


def num_threads() -> int:
    """Numba threads a parallel kernel uses when called from this thread (starts numba's
    threading layer, as the first parallel kernel would)."""
    return int(numba.get_num_threads())


def max_threads() -> int:
    """Numba threads a parallel kernel may use at most (``NUMBA_NUM_THREADS``)."""
    config: Any = numba.config
    return int(config.NUMBA_NUM_THREADS)


def cache_dir() -> str:
    """``NUMBA_CACHE_DIR`` as numba read it; empty when unset (the cache then lives beside
    the sources)."""
    return str(getattr(numba.config, "CACHE_DIR", "") or "")


@dataclass(frozen=True)
class ThreadingInfo:
    """What :func:`threading_info` reports."""

    layer: str
    """The threading layer numba runs parallel kernels on: ``"tbb"``, ``"omp"`` or
    ``"workqueue"`` (``numba.threading_layer()``)."""
    asked: str
    """The layer asked of numba (``numba.config.THREADING_LAYER``), e.g. ``"safe"``."""
    user_layer: str | None
    """``NUMBA_THREADING_LAYER`` from the environment, which fricenv leaves as it is."""
    tbb_loaded: bool
    """Whether numba's TBB layer could be loaded in this process."""
    tbb_path: str | None
    """The ``libtbb`` fricenv loaded by its path; None if it loaded none (the loader found
    it, or there is none)."""
    thread_safe: bool
    """Whether parallel kernels may run from several Python threads at once."""
    serialised: bool
    """Whether fricenv runs its parallel kernel calls one at a time (behind one lock)."""
    fork_safe: bool
    """Whether a process forked after a parallel kernel ran can run them too."""
    num_threads: int
    """Numba threads a parallel kernel uses when called from this thread."""
    max_threads: int
    """Numba threads launched (``NUMBA_NUM_THREADS``)."""


def threading_info() -> ThreadingInfo:
    """How fricenv's parallel kernels run in this process: numba's threading layer, whether
    TBB loaded and from where, whether calls are serialised, the thread count. Calling it
    starts numba's threading layer, as the first parallel kernel would, so set
    ``NUMBA_THREADING_LAYER`` or ``NUMBA_NUM_THREADS`` before."""
    serialised = parallel_section() is _PARALLEL_LOCK
    layer = str(numba.threading_layer())
    config: Any = numba.config
    gnu_omp = layer == "omp" and sys.platform.startswith("linux")  # (GNU OpenMP there)
    return ThreadingInfo(
        layer=layer, asked=str(config.THREADING_LAYER),
        user_layer=os.environ.get("NUMBA_THREADING_LAYER") or None,
        tbb_loaded=TBB_LOADS, tbb_path=TBB_PATH,
        thread_safe=layer in THREAD_SAFE_LAYERS, serialised=serialised,
        fork_safe=not gnu_omp, num_threads=int(numba.get_num_threads()),
        max_threads=int(config.NUMBA_NUM_THREADS))


def kernel(fn: Callable | None = None, *, takes_kernels: bool = False,
           called_once: bool = False, allocates: bool = False, parallel: bool = False,
           fastmath: set[str] | None = None, nogil: bool = False) -> Any:
    """Compile ``fn`` as a fricenv kernel; usable bare (``@kernel``) or with options.

    ``takes_kernels``: ``fn`` is a generic body that takes other kernels as arguments; numba
    inlines it at its IR level into each caller, so that the callers cache (see the module
    docstring). ``called_once``: ``fn`` is called from one place in the package, a step
    loop, and numba inlines it there at its IR level too: its body is typed once either way,
    so this costs no compile time, and it spares a call per step that LLVM does not inline
    for a body of this size (the closed form's slip and stick steps: 1.6 times the time of
    a long ``run_stats`` when called). ``allocates``:
    keep numba's reference-counting runtime (see the module docstring). ``parallel``: the
    function holds a ``prange`` loop. ``fastmath``: LLVM fast-math flags for this function
    only (e.g. ``{"reassoc", "contract"}`` for sums whose order may change). ``nogil``:
    release the GIL while the kernel runs when called from Python (the public entry
    kernels, which ``fricenv.calls`` runs in a worker thread so that Ctrl-C stays live).
    """
    options: dict[str, Any] = {"cache": True, "error_model": "numpy"}
    if not allocates:
        options["_nrt"] = False
    if takes_kernels or called_once:
        options["inline"] = "always"
    if parallel:
        options["parallel"] = True
    if fastmath:
        options["fastmath"] = fastmath
    if nogil:
        options["nogil"] = True
    decorate = njit(**options)

    def build(f: Callable) -> Any:
        dispatcher = decorate(f)
        if not (takes_kernels or called_once):  # (inlined: never compiled on its own)
            _compile_unliteral(dispatcher)
        return dispatcher

    return build if fn is None else build(fn)


def _compile_unliteral(dispatcher: Any) -> None:
    """Compile ``dispatcher``, when another kernel calls it, for its arguments' plain types.

    A module constant passed as an argument (``_cget(cx, W_I_E1)``, ``_scan_cap(P, False)``)
    reaches numba as a literal type, and numba compiles the callee anew for each literal
    value: one kernel became six specialisations, each a full compile. Kernels never
    depend on a literal argument, so calls from compiled code resolve to one signature per
    kernel. (numba offers no option for this; the dispatcher's call template is the one
    place every such call passes.)"""
    template = dispatcher.get_call_template

    def get_call_template(args: tuple, kws: dict) -> Any:
        return template(tuple(types.unliteral(a) for a in args),
                        {k: types.unliteral(v) for k, v in kws.items()})

    dispatcher.get_call_template = get_call_template
