"""An atomic counter for numba kernels whose threads share work out as they go.

numba's ``prange`` hands each thread a fixed, contiguous share of the iterations (its
OpenMP layer schedules statically), so when iterations differ in cost, or the host slows
one thread, the others wait at the end. A kernel can instead run one ``prange`` iteration
per worker and let the workers claim work from a shared counter with :func:`fetch_add`.
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
