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

The compilation flags decide the machine code, and with it the last bit of a result:
changing a kernel's ``inline`` or ``fastmath`` changes what it computes, not only how fast.

Threading layer
---------------
The parallel kernels (sweeps, ``cell_statistics``, the vector environment from
``PARALLEL_MIN_PLANTS`` plants) run on numba's threading layer, which numba picks when the
first of them starts. Its default here is GNU OpenMP, which is not fork-safe: after any
parallel kernel has run, a ``multiprocessing`` pool, ``ProcessPoolExecutor`` or joblib's
multiprocessing backend started by ``fork`` prints ``fork() called from a process already
using GNU OpenMP`` and its workers hang or crash. This module therefore asks numba for the
``"safe"`` layer, Intel TBB (a dependency where its wheels exist): safe after ``fork`` and
safe to call from several Python threads at once (Dask's threaded scheduler, a thread per
environment). Where TBB cannot be loaded it asks for ``"forksafe"``, which on GNU OpenMP
systems is numba's ``workqueue`` layer: fork-safe too, but its parallel kernels must not run
from two Python threads at the same time. A ``NUMBA_THREADING_LAYER`` set in the
environment is left as it is.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from typing import Any

import numba
from numba import njit


def _tbb_loads() -> bool:
    """Whether numba's TBB threading layer can be loaded: the ``tbb`` wheel is installed,
    the loader finds its library and numba accepts its version. Asked the way numba asks
    when it starts a layer (its version check loads the library, then its TBB pool)."""
    try:
        from numba.np.ufunc.parallel import _check_tbb_version_compatible

        _check_tbb_version_compatible()
        importlib.import_module("numba.np.ufunc.tbbpool")
    except (ImportError, OSError):
        return False
    return True


def choose_threading_layer() -> str:
    """Ask numba for a fork-safe threading layer (see the module docstring) unless the user
    chose one with ``NUMBA_THREADING_LAYER``; the layer asked for. It takes effect if no
    parallel kernel has run yet in this process."""
    config: Any = numba.config  # (numba sets its options as module attributes at run time)
    if os.environ.get("NUMBA_THREADING_LAYER"):
        return str(config.THREADING_LAYER)
    config.THREADING_LAYER = "safe" if _tbb_loads() else "forksafe"
    return str(config.THREADING_LAYER)


THREADING_LAYER = choose_threading_layer()  # on import, before any kernel can run


def kernel(fn: Callable | None = None, *, inline: bool = False, allocates: bool = False,
           parallel: bool = False, fastmath: set[str] | None = None,
           nogil: bool = False) -> Any:
    """Compile ``fn`` as a fricenv kernel; usable bare (``@kernel``) or with options.

    ``inline``: numba inlines the function into each caller at its IR level (small hot
    helpers, and generic bodies that take another kernel as an argument). ``allocates``:
    keep numba's reference-counting runtime (see the module docstring). ``parallel``: the
    function holds a ``prange`` loop. ``fastmath``: LLVM fast-math flags for this function
    only (e.g. ``{"reassoc", "contract"}`` for sums whose order may change). ``nogil``:
    release the GIL while the kernel runs when called from Python (the public entry
    kernels, which ``fricenv.calls`` runs in a worker thread so that Ctrl-C stays live).
    """
    options: dict[str, Any] = {"cache": True, "error_model": "numpy"}
    if not allocates:
        options["_nrt"] = False
    if inline:
        options["inline"] = "always"
    if parallel:
        options["parallel"] = True
    if fastmath:
        options["fastmath"] = fastmath
    if nogil:
        options["nogil"] = True
    decorate = njit(**options)
    return decorate if fn is None else decorate(fn)
