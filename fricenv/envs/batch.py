"""Numba kernels of the native vector environment: a batch of plants stepped in one call.

Each plant is stepped by the single environment's body (``kernels.control_interval``,
``kernels.write_obs``), so the two agree bit for bit. The bodies here are written once and
take the per-plant step as their first argument (``advance_ws``, ``step_range``);
:mod:`fricenv.envs.steppers` builds each method's entry kernels from them. The entry
kernels take the batch's arrays one by one, as Python passes them fastest; inside, they
travel as one :class:`Batch`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import prange

from fricenv.envs.kernels import (
    AUTORESET_NEXT_STEP,
    AUTORESET_SAME_STEP,
    Plant,
    actions_finite,
    control_interval,
    episode_from_uniforms,
    start_episode,
    write_obs,
)
from fricenv.envs.tables import (
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
    IV_N_RESET,
    IV_N_TASKS,
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


class Batch(NamedTuple):
    """A batch step's arrays (see ``step_batch_with``) and the two settings it reads from
    ``ivars``."""

    table: np.ndarray  # a row per plant (tables.T_*)
    cfg: np.ndarray  # the kernels' configuration
    A: np.ndarray  # the actions, a row per plant
    obs: np.ndarray  # current and final observations
    res: np.ndarray  # a row per result, a column per plant
    flags: np.ndarray
    counters: np.ndarray
    draws: np.ndarray  # buffered uniforms of each plant's next episodes
    bounds: np.ndarray  # [draw_lo, draw_hi]
    max_steps: int  # steps of an episode
    mode: int  # autoreset mode


@kernel
def _plant(table, i):
    """Plant ``i``'s arrays: views of its row of ``table``."""
    row = table[i]
    return Plant(row[T_P:T_S], row[T_S:T_CTRL], row[T_CTRL:T_STATS], row[T_STATS:T_NEW_P],
                 row[T_WORK:])


@kernel(takes_kernels=True)
def _plant_step(advance_ws, i, b) -> int:
    """Body of the batch step for plant ``i`` of the :class:`Batch` ``b`` (see
    ``step_batch_with``).

    Marks in ``flags[F_DID_RESET, i]`` a plant whose next episode must start now; the
    caller starts it (``_start_next``).
    """
    flags = b.flags
    res = b.res
    obs = b.obs
    flags[F_DID_RESET, i] = False
    if b.mode == AUTORESET_NEXT_STEP and flags[F_AUTORESET, i]:
        for k in range(res.shape[0]):
            res[k, i] = 0.0
        flags[F_TERMINATED, i] = False
        flags[F_TRUNCATED, i] = False
        flags[F_AUTORESET, i] = False
        flags[F_DID_RESET, i] = True
        return 0
    plant = _plant(b.table, i)
    status = control_interval(advance_ws, plant, b.cfg, b.A[i], res[:, i])
    if status != 0:
        return status
    term = write_obs(plant.P, plant.S, plant.ctrl, b.cfg, obs[OB_NOW, i], plant.work)
    res[R_TERM, i] = 1.0 if term else 0.0
    b.counters[CT_STEPS, i] += 1
    trunc = b.counters[CT_STEPS, i] >= b.max_steps
    flags[F_TERMINATED, i] = term
    flags[F_TRUNCATED, i] = trunc
    done = term or trunc
    if b.mode == AUTORESET_SAME_STEP and done:
        for k in range(obs.shape[2]):
            obs[OB_FINAL, i, k] = obs[OB_NOW, i, k]
        flags[F_DID_RESET, i] = True
    else:
        flags[F_AUTORESET, i] = done
    return 0


@kernel
def _start_next(i, b):
    """Start plant ``i``'s next episode from its next buffered row of draws.

    The caller refills a spent buffer before the next call; the modulo only keeps a caller
    that forgets from reading outside the buffer.
    """
    table = b.table
    counters = b.counters
    row = counters[CT_CURSOR, i] % b.draws.shape[1]
    new_P = table[i, T_NEW_P:T_NEW_INIT]
    new_init = table[i, T_NEW_INIT:T_WORK]
    episode_from_uniforms(b.draws[i, row], b.bounds, b.cfg, new_P, new_init)
    counters[CT_CURSOR, i] += 1
    start_episode(_plant(table, i), b.cfg, new_P, new_init, b.obs[OB_NOW, i])
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
def step_range_with(advance_ws, lo, hi, b) -> None:
    """Step plants ``lo`` to ``hi - 1`` of the :class:`Batch` ``b`` (the body of both batch
    kernels).

    The per-plant body is inlined here: a call per plant would pass the batch's array
    structures each time, which measured as much as a sixth of a plant-step. Kernels built
    on it (``_step_range_exact``, ...) are the serial range of both batch kernels.
    """
    for i in range(lo, hi):
        b.counters[CT_STATUS, i] = _plant_step(advance_ws, i, b)
        if b.flags[F_DID_RESET, i]:
            _start_next(i, b)


@kernel(takes_kernels=True)
def step_batch_with(step_range, table, cfg, A, obs, res, flags, counters, draws, bounds,
                    ivars) -> int:
    """Step N plants with autoreset in one call.

    The batch's arrays (see "Vector kernels' arrays" above): plant ``table``, ``obs``
    (current and final observations), ``res``, ``flags``, ``counters``; ``ivars`` =
    [max_episode_steps, autoreset mode, n_reset, n_empty, the parallel kernel's tasks].
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
    ``counters[CT_STATUS]``). ``step_range(lo, hi, batch)`` steps the plants (a
    ``step_range_with`` of the method's own).
    """
    bad = first_bad_action(A, flags[F_AUTORESET], ivars[IV_MODE])
    if bad >= 0:
        return -(bad + 1)
    step_range(0, table.shape[0], Batch(table, cfg, A, obs, res, flags, counters, draws,
                                        bounds, ivars[IV_MAX_STEPS], ivars[IV_MODE]))
    return _count(flags, counters, draws.shape[1], ivars)


#: Tasks per numba thread of the parallel batch step (``ivars[IV_N_TASKS]`` holds their
#: number, set by the caller from its thread count: numba's own count, read inside a
#: kernel, would keep the kernel out of the cache): each task is one call of the method's
#: range kernel over a contiguous share of the plants, so the call's cost (the batch's
#: array structures, passed by value) is shared by that many plant-steps, while a free
#: thread can still take a share a delayed one has not started. Tasks of four plants
#: each made the step 10-14 % slower at 256 and 1024 plants.
TASKS_PER_THREAD = 4


@kernel(takes_kernels=True)
def step_batch_parallel_with(step_range, table, cfg, A, obs, res, flags, counters, draws,
                             bounds, ivars) -> int:
    """``step_batch`` with its plants shared between numba's threads by a plain ``prange``
    over ``ivars[IV_N_TASKS]`` tasks (``TASKS_PER_THREAD`` per thread, set by the caller),
    each a contiguous share of the plants stepped by ``step_range`` (the serial kernel's).

    numba cuts the tasks into one contiguous share per thread and hands the shares to its
    threading layer; on TBB they are tasks, and a free thread may take one that no other
    thread has started, so a thread the host delays need not hold the step up. A
    scheduler of its own (pairs of workers claiming chunks of plants from an atomic counter,
    from opposite ends of the batch, and the vector env stepping serially for a while when
    workers kept coming late) measured no faster than a plain ``prange`` on TBB, in
    alternating rounds at 16, 256 and 4096 plants on a loaded host (docs/performance.md,
    "Sharing plants between threads").

    The range body is called, not inlined into the loop: numba's parallel passes drop
    writes made inside a ``prange`` body through a record's field (a :class:`Batch`'s
    arrays), as if to a temporary; a call keeps them. Each plant reads and writes only its
    own slots, so the result is identical to the serial kernel whatever the thread count
    and order. Like the other kernels it allocates nothing, so it runs without numba's
    reference counting (``_nrt=False``), whose atomic updates on the shared batch arrays the
    threads would otherwise fight over.
    """
    bad = first_bad_action(A, flags[F_AUTORESET], ivars[IV_MODE])
    if bad >= 0:
        return -(bad + 1)
    # (made by its class here: numba's parallel lowering rebuilds a record the loop uses
    # by the name of the call that made it)
    b = Batch(table, cfg, A, obs, res, flags, counters, draws, bounds, ivars[IV_MAX_STEPS],
              ivars[IV_MODE])
    n = table.shape[0]
    n_tasks = max(1, min(n, ivars[IV_N_TASKS]))
    for task in prange(n_tasks):
        step_range(task * n // n_tasks, (task + 1) * n // n_tasks, b)
    return _count(flags, counters, draws.shape[1], ivars)


@kernel
def start_batch(table, cfg, mask, obs, flags, counters) -> None:
    """Begin episodes for the plants selected by ``mask``, from their next-episode columns."""
    for i in range(table.shape[0]):
        if mask[i]:
            start_episode(_plant(table, i), cfg, table[i, T_NEW_P:T_NEW_INIT],
                          table[i, T_NEW_INIT:T_WORK], obs[OB_NOW, i])
            counters[CT_STEPS, i] = 0
            flags[F_AUTORESET, i] = False
