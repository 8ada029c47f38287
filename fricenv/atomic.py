"""An atomic counter for numba kernels whose threads share work out as they go.

numba's ``prange`` cuts its iterations into one contiguous share per thread before its
threading layer (TBB here) runs them, so when iterations differ in cost by orders of
magnitude, as a sweep's cells do, the threads that drew cheap ones wait at the end. A
kernel can instead run one ``prange`` iteration per worker and let the workers claim work
from a shared counter with :func:`fetch_add`; the sweep's cell kernel does (and another
thread stops a run by moving that counter past the last cell). The vector environment's
plants cost about the same each, and a plain ``prange`` steps them as fast (see
docs/performance.md, "Sharing plants between threads").
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def fetch_add(typingctx, arr, idx, inc):
    """Atomically add ``inc`` to ``arr[idx]`` (a writable, contiguous 1-d int64 array);
    return the old value.

    numba has no atomics of its own; this is LLVM's ``atomicrmw add``. Monotonic ordering
    suffices: the counter only hands out indices, and what the workers write is published
    by the barrier that ends the parallel loop. Like a raw pointer, ``idx`` is neither
    bounds-checked nor wrapped when negative: the caller owns the slot.
    """
    if not (isinstance(arr, types.Array) and arr.dtype == types.int64 and arr.ndim == 1
            and arr.layout == "C" and arr.mutable):
        return None
    sig = types.int64(arr, types.intp, types.int64)

    def codegen(context, builder, signature, args):
        arr_t = signature.args[0]
        ary = context.make_array(arr_t)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, arr_t, ary, [args[1]])
        return builder.atomic_rmw("add", ptr, args[2], "monotonic")

    return sig, codegen
