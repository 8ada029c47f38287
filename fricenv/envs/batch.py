"""Numba kernels of the native vector environment: a batch of plants stepped in one call.

Each plant is stepped by the single environment's body (``kernels.control_interval``,
``kernels.write_obs``), so the two agree bit for bit. The bodies here are written once and
take the per-plant step as their first argument (``step_range``, ``advance_ws``); the entry
kernels of each core method are in :mod:`fricenv.envs.steppers`, those that take the
method at run time at the end of this module.
"""

from __future__ import annotations

from numba import prange

from fricenv.atomic import fetch_add
from fricenv.core import advance_ws
from fricenv.envs.kernels import (
    AUTORESET_NEXT_STEP,
    AUTORESET_SAME_STEP,
    actions_finite,
    control_interval,
    episode_from_uniforms,
    start_episode,
    write_obs,
)
from fricenv.envs.tables import (
    COUNTER_STRIDE,
    CT_CURSOR,
    CT_STATUS,
    CT_STEPS,
    F_AUTORESET,
    F_DID_RESET,
    F_TERMINATED,
    F_TRUNCATED,
    IV_MAX_STEPS,
    IV_MODE,
    IV_N_EMPTY,
    IV_N_LATE,
    IV_N_RESET,
    IV_N_WORKERS,
    N_IVARS,
    OB_FINAL,
    OB_NOW,
    R_TERM,
    T_CTRL,
    T_NEW_INIT,
    T_NEW_P,
    T_P,
    T_S,
    T_STATS,
    T_WORK,
)
from fricenv.jit import kernel

# Plants a thread of the parallel kernel claims at a time in the middle of its region:
# small, so that the threads finish together. Each worker's first claim is a big cell
# instead (see ``_cells``), because every claim is an atomic add on a counter whose cache
# line the two threads pass back and forth.
CHUNK = 8


@kernel
def _plant_rows(table, i):
    """Plant ``i``'s parameters, state, excitation, stats and workspace: views of its row."""
    row = table[i]
    return (row[T_P:T_S], row[T_S:T_CTRL], row[T_CTRL:T_STATS], row[T_STATS:T_NEW_P],
            row[T_WORK:])


@kernel(takes_kernels=True)
def _plant_step(advance_ws, i, table, cfg, A, obs, res, flags, counters, max_steps,
                mode) -> int:
    """Body of the batch step for plant ``i`` (see ``step_batch``).

    Marks in ``flags[F_DID_RESET, i]`` a plant whose next episode must start now; the
    caller starts it (``_start_next``).
    """
    flags[F_DID_RESET, i] = False
    if mode == AUTORESET_NEXT_STEP and flags[F_AUTORESET, i]:
        for k in range(res.shape[0]):
            res[k, i] = 0.0
        flags[F_TERMINATED, i] = False
        flags[F_TRUNCATED, i] = False
        flags[F_AUTORESET, i] = False
        flags[F_DID_RESET, i] = True
        return 0
    Pi, Si, ci, sti, wi = _plant_rows(table, i)
    status = control_interval(advance_ws, Pi, Si, ci, cfg, A[i], sti, res[:, i], wi)
    if status != 0:
        return status
    term = write_obs(Pi, Si, ci, cfg, obs[OB_NOW, i], wi)
    res[R_TERM, i] = 1.0 if term else 0.0
    counters[CT_STEPS, i] += 1
    trunc = counters[CT_STEPS, i] >= max_steps
    flags[F_TERMINATED, i] = term
    flags[F_TRUNCATED, i] = trunc
    done = term or trunc
    if mode == AUTORESET_SAME_STEP and done:
        for k in range(obs.shape[2]):
            obs[OB_FINAL, i, k] = obs[OB_NOW, i, k]
        flags[F_DID_RESET, i] = True
    else:
        flags[F_AUTORESET, i] = done
    return 0


@kernel
def _start_next(i, table, cfg, obs, counters, draws, bounds):
    """Start plant ``i``'s next episode from its next buffered row of draws.

    The caller refills a spent buffer before the next call; the modulo only keeps a caller
    that forgets from reading outside the buffer.
    """
    row = counters[CT_CURSOR, i] % draws.shape[1]
    new_P = table[i, T_NEW_P:T_NEW_INIT]
    new_init = table[i, T_NEW_INIT:T_WORK]
    episode_from_uniforms(draws[i, row], bounds, cfg, new_P, new_init)
    counters[CT_CURSOR, i] += 1
    Pi, Si, ci, _, wi = _plant_rows(table, i)
    start_episode(Pi, Si, ci, cfg, new_P, new_init, obs[OB_NOW, i], wi)
    counters[CT_STEPS, i] = 0


@kernel
def first_bad_action(A, autoreset, mode) -> int:
    """The first plant whose action is not finite, or -1 (a plant that next-step mode
    resets instead of stepping ignores its action, so it is not checked)."""
    for i in range(A.shape[0]):
        if mode == AUTORESET_NEXT_STEP and autoreset[i]:
            continue
        if not actions_finite(A[i]):
            return i
    return -1


@kernel
def _count(flags, counters, n_rows, ivars) -> int:
    """Write the reset and empty-buffer counts to ``ivars``; return the failure count."""
    n_failed = 0
    n_reset = 0
    n_empty = 0
    for i in range(flags.shape[1]):
        if counters[CT_STATUS, i] != 0:
            n_failed += 1
        if flags[F_DID_RESET, i]:
            n_reset += 1
            if counters[CT_CURSOR, i] >= n_rows:
                n_empty += 1
    ivars[IV_N_RESET] = n_reset
    ivars[IV_N_EMPTY] = n_empty
    return n_failed


@kernel(takes_kernels=True)
def step_range_with(advance_ws, lo, hi, table, cfg, A, obs, res, flags, counters, draws,
                    bounds, max_steps, mode) -> None:
    """Step plants ``lo`` to ``hi - 1`` (the body of both batch kernels).

    The per-plant body is inlined here: a call per plant would pass the batch's array
    structures each time, which measured as much as a sixth of a plant-step.
    """
    for i in range(lo, hi):
        counters[CT_STATUS, i] = _plant_step(advance_ws, i, table, cfg, A, obs, res, flags,
                                             counters, max_steps, mode)
        if flags[F_DID_RESET, i]:
            _start_next(i, table, cfg, obs, counters, draws, bounds)


@kernel(takes_kernels=True)
def step_batch_with(step_range, table, cfg, A, obs, res, flags, counters, draws, bounds,
                    ivars) -> int:
    """Step N plants with autoreset in one call.

    The batch's arrays (see "Vector kernels' arrays" above): plant ``table``, ``obs``
    (current and final observations), ``res``, ``flags``, ``counters``; ``ivars`` =
    [max_episode_steps, autoreset mode, n_reset, n_empty, n_workers, work counters...].
    ``F_AUTORESET`` marks a plant whose episode ended on the previous call. NEXT_STEP: such
    a plant is reset instead of stepped, with reward 0. SAME_STEP: a plant whose episode
    ends now is reset at once, its last observation saved in ``obs[OB_FINAL]``. DISABLED:
    the caller resets. A reset starts the episode made of the uniforms ``draws[i, cursor]``
    (scaled by ``bounds``, built in the plant's next-episode columns) and advances its
    cursor. ``F_DID_RESET`` marks the plants reset now; the kernel writes their number to
    ``ivars[2]`` and, in ``ivars[3]``, how many of them used their last buffered row (the
    caller refills those before the next call). Actions are all checked before any plant
    moves: a non-finite one returns its plant's index + 1 as a negative number. Otherwise
    returns the number of plants whose integration failed (their codes are in
    ``counters[CT_STATUS]``).
    """
    mode = ivars[IV_MODE]
    bad = first_bad_action(A, flags[F_AUTORESET], mode)
    if bad >= 0:
        return -(bad + 1)
    step_range(0, table.shape[0], table, cfg, A, obs, res, flags, counters, draws, bounds,
               ivars[IV_MAX_STEPS], mode)
    return _count(flags, counters, draws.shape[1], ivars)


@kernel
def _region(worker, n_workers, n):
    """Plants [lo, hi) of the region that ``worker`` shares with its partner (workers 2r
    and 2r + 1 share region r; with an odd count the last worker has a region alone), sized
    by its number of workers so that every worker starts with an equal share."""
    first = worker - worker % 2
    return first * n // n_workers, min(first + 2, n_workers) * n // n_workers


@kernel
def _cells(lo, hi):
    """How the region [lo, hi) is cut into claimable cells: (big, n_cells).

    The region's middle half (at least two chunks) is cut into chunks of ``CHUNK``
    plants; the rest forms two big cells of ``big`` plants, the first and the last. A pair
    of workers on time each claims one big cell first, from its own end, and the two meet
    in the middle chunks: half the claims of a region all in chunks (the counter's cache
    line moves between the threads at each claim; 1-6 % of a step in paired rounds). A
    big cell of a quarter still lets a worker slowed to half its partner's speed end with
    a third of the region, as a balanced split would. A region too small for that
    (``big == 0``) is all chunks.
    """
    n = hi - lo
    middle = min(n, CHUNK * max(2, (n + 2 * CHUNK - 1) // (2 * CHUNK)))
    big = (n - middle) // 2
    n_chunks = (n - 2 * big + CHUNK - 1) // CHUNK
    return big, n_chunks + (2 if big > 0 else 0)


@kernel
def _cell(lo, hi, big, n_cells, done, from_back):
    """Plants [start, end) of a worker's ``done``-th claim in the region [lo, hi), cut as
    ``_cells`` says.

    Both ends count cells on one grid, so when the region's counter has handed out its
    ``n_cells`` claims, a front worker's first a cells and a back worker's first b =
    n_cells - a never overlap and leave nothing out (a worker on time alone takes both big
    cells).
    """
    k = n_cells - 1 - done if from_back else done
    if big > 0:
        if k == 0:
            return lo, lo + big
        if k == n_cells - 1:
            return hi - big, hi
        k -= 1
    start = lo + big + k * CHUNK
    return start, min(hi - big, start + CHUNK)


@kernel(takes_kernels=True)
def step_batch_parallel_with(step_range, table, cfg, A, obs, res, flags, counters, draws,
                             bounds, ivars) -> int:
    """``step_batch`` on ``ivars[4]`` workers (one ``prange`` iteration each) that share
    the plants out as they go.

    Plants differ in cost (a switch interval costs several whole-interval steps), and the
    host may slow one thread, so a fixed split leaves one thread waiting for the other.
    Instead the plants are split into one region per pair of workers; in a region, one
    worker steps cells of plants (``_cells``: a big one, then chunks of ``CHUNK``) from the
    front and the other from the back, each claiming its next cell from the region's
    counter in ``ivars`` (bumped atomically), until the region's cells are handed out.
    Working from opposite ends keeps the two off each other's cache lines of the per-plant
    rows of ``res``, ``flags`` and ``counters`` (chunks handed out in turn from one end
    made the kernel slower than the serial one). Without counter slots in ``ivars`` the
    plants are stepped in order.

    Each plant reads and writes only its own slots, so the result is identical to the
    serial kernel whatever the worker or thread count and order. Like the other kernels it
    allocates nothing, so it runs without numba's reference counting (``_nrt=False``),
    whose atomic updates on the shared batch arrays the threads would otherwise fight over.

    ``ivars[IV_N_LATE]`` counts the workers that found their region (of at least four
    cells) already handed out: their thread got a CPU only after its partner had done
    all the work, and the step waited for it at the loop's end. On a machine busy with
    other processes that wait is a scheduler time slice, and the caller should step
    serially for a while (the vector env does).
    """
    mode = ivars[IV_MODE]
    bad = first_bad_action(A, flags[F_AUTORESET], mode)
    if bad >= 0:
        return -(bad + 1)
    n = table.shape[0]
    max_steps = ivars[IV_MAX_STEPS]
    n_workers = min(max(1, ivars[IV_N_WORKERS]),
                    2 * ((ivars.shape[0] - N_IVARS) // COUNTER_STRIDE))
    if n_workers == 0:
        step_range(0, n, table, cfg, A, obs, res, flags, counters, draws, bounds, max_steps,
                   mode)
        return _count(flags, counters, draws.shape[1], ivars)
    for r in range((n_workers + 1) // 2):
        ivars[N_IVARS + r * COUNTER_STRIDE] = 0
    ivars[IV_N_LATE] = 0
    for worker in prange(n_workers):
        lo, hi = _region(worker, n_workers, n)
        big, n_cells = _cells(lo, hi)
        counter = N_IVARS + (worker // 2) * COUNTER_STRIDE
        done = 0
        while fetch_add(ivars, counter, 1) < n_cells:
            start, end = _cell(lo, hi, big, n_cells, done, worker % 2 == 1)
            step_range(start, end, table, cfg, A, obs, res, flags, counters, draws, bounds,
                       max_steps, mode)
            done += 1
        if done == 0 and n_cells >= 4:  # (a worker alone in its region is never late)
            fetch_add(ivars, IV_N_LATE, 1)
    return _count(flags, counters, draws.shape[1], ivars)


@kernel
def start_batch(table, cfg, mask, obs, flags, counters) -> None:
    """Begin episodes for the plants selected by ``mask``, from their next-episode columns."""
    for i in range(table.shape[0]):
        if mask[i]:
            Pi, Si, ci, _, wi = _plant_rows(table, i)
            start_episode(Pi, Si, ci, cfg, table[i, T_NEW_P:T_NEW_INIT],
                          table[i, T_NEW_INIT:T_WORK], obs[OB_NOW, i], wi)
            counters[CT_STEPS, i] = 0
            flags[F_AUTORESET, i] = False


@kernel
def _step_range(lo, hi, table, cfg, A, obs, res, flags, counters, draws, bounds, max_steps,
                mode) -> None:
    """``step_range_with`` by ``core.advance_ws``."""
    step_range_with(advance_ws, lo, hi, table, cfg, A, obs, res, flags, counters, draws,
                    bounds, max_steps, mode)


@kernel
def step_batch(table, cfg, A, obs, res, flags, counters, draws, bounds, ivars) -> int:
    """``step_batch_with`` by ``core.advance_ws``."""
    return step_batch_with(_step_range, table, cfg, A, obs, res, flags, counters, draws,
                           bounds, ivars)


@kernel(parallel=True)
def step_batch_parallel(table, cfg, A, obs, res, flags, counters, draws, bounds, ivars) -> int:
    """``step_batch_parallel_with`` by ``core.advance_ws``."""
    return step_batch_parallel_with(_step_range, table, cfg, A, obs, res, flags, counters,
                                    draws, bounds, ivars)
