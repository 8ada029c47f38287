"""Numba kernels of the RL environments: action scaling, one control interval, reward, obs.

The single environment and the native vector environment call the same inner functions, so
they agree bit for bit. The step kernels allocate nothing of their own (only
``sample_interval``, used for rendering, works on copies) and run on the physics core's
stats-only path (``core.advance``): an environment step integrates to the next control
instant and keeps no trajectory.

Kernels that allocate nothing are compiled without numba's reference-counting runtime
(``_nrt=False``, see ``fricenv.jit``): otherwise every per-plant call does atomic count
updates on the batch arrays, which threads then fight over.

These kernels inline much of ``fricenv.core``; their numba cache is keyed on the whole
package's source (``fricenv._numba_cache``), so editing the core recompiles them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from fricenv.atomic import fetch_add
from fricenv.core import (
    W_C1,
    W_C2,
    W_PH1,
    W_PH2,
    W_S1,
    W_S2,
    advance,
    advance_ws,
    initial_mode,
    initial_state,
    reset_stats,
)

# The arrays' layouts (declared in .tables; importable from here too).
from fricenv.envs.tables import (  # noqa: F401
    C_ACTION_MODE,
    C_ATOL,
    C_DNU,
    C_DT,
    C_DU,
    C_EFFORT_NORM,
    C_G1,
    C_G2,
    C_INCREMENTAL,
    C_MAX_EVENTS,
    C_METHOD,
    C_NU_HI,
    C_NU_LO,
    C_NU_START,
    C_RTOL,
    C_U0_START,
    C_U_HI,
    C_U_LO,
    C_V_LIM,
    C_W_EFFORT,
    C_W_STICK,
    C_W_VEL,
    C_X_LIM,
    COUNTER_STRIDE,
    CT_CURSOR,
    CT_STATUS,
    CT_STEPS,
    D_B1,
    D_B3,
    D_ETA,
    D_LAM,
    D_PHI1,
    D_PHI2,
    D_V,
    D_V0,
    D_X0,
    D_XFK,
    D_XFS,
    F_AUTORESET,
    F_DID_RESET,
    F_TERMINATED,
    F_TRUNCATED,
    I_NU,
    I_PHI1,
    I_PHI2,
    I_U0,
    I_V0,
    I_X0,
    IV_MAX_STEPS,
    IV_MODE,
    IV_N_EMPTY,
    IV_N_LATE,
    IV_N_RESET,
    IV_N_WORKERS,
    N_CFG,
    N_COUNTERS,
    N_FLAGS,
    N_INIT,
    N_IVARS,
    N_OBS,
    N_RES,
    N_TABLE,
    O_COS1,
    O_COS2,
    O_NU,
    O_SIN1,
    O_SIN2,
    O_STICK,
    O_U0,
    O_VR,
    O_X,
    OB_FINAL,
    OB_NOW,
    R_EFFORT,
    R_MEAN_VR,
    R_REWARD,
    R_STICK,
    R_TERM,
    R_VAR,
    T_CTRL,
    T_NEW_INIT,
    T_NEW_P,
    T_P,
    T_S,
    T_STATS,
    T_WORK,
)
from fricenv.jit import kernel
from fricenv.layout import (
    METHOD_EVENT,
    METHOD_EXACT,
    S_MODE,
    S_PHI1,
    S_PHI2,
    S_T,
    S_V,
    S_X,
    ST_STICK_TIME,
    ST_VR2_INT,
    STATUS_NONFINITE,
)
from fricenv.params import P_B1, P_B3, P_LAM, P_U1, P_U2, P_V, P_W1, P_W2, P_XFK, P_XFS

# Floor of V^2 in the velocity-fluctuation term (a belt at rest would divide by 0).
V2_FLOOR = 1e-12

# Action modes (index into scenes.ACTION_MODES).
MODE_AMPLITUDE, MODE_FREQUENCY, MODE_BOTH = 0, 1, 2

METHOD_AUTO = -1
TWO_PI = 2.0 * math.pi

# Status returned when an action is not finite (the core's codes are >= 0).
STATUS_BAD_ACTION = -1

# Autoreset modes of the vector kernel.
AUTORESET_NEXT_STEP, AUTORESET_SAME_STEP, AUTORESET_DISABLED = 0, 1, 2

# Plants a thread of the parallel kernel claims at a time in the middle of its region:
# small, so that the threads finish together. Each worker's first claim is a big cell
# instead (see ``_cells``), because every claim is an atomic add on a counter whose cache
# line the two threads pass back and forth.
CHUNK = 8


@kernel
def _clip(v, lo, hi):
    return lo if v < lo else (hi if v > hi else v)


@kernel
def actions_finite(a) -> bool:
    for k in range(a.shape[0]):
        if not math.isfinite(a[k]):
            return False
    return True


@kernel(inline=True)
def set_excitation(P, ctrl, cfg) -> None:
    """Write the tone amplitudes and the second tone's frequency from (u0, nu).

    The core accumulates tone phases in the state, so retuning here between two calls of
    ``advance`` keeps every phase continuous.
    """
    P[P_U1] = cfg[C_G1] * ctrl[0]
    P[P_U2] = cfg[C_G2] * ctrl[0]
    P[P_W2] = ctrl[1] * P[P_W1]


@kernel(inline=True)
def apply_action(ctrl, cfg, a) -> None:
    """Map a normalised action in [-1, 1] (clipped) to (u0, nu), absolute or incremental."""
    mode = int(cfg[C_ACTION_MODE])
    incremental = cfg[C_INCREMENTAL] != 0.0
    j = 0
    if mode != MODE_FREQUENCY:
        ai = _clip(a[j], -1.0, 1.0)
        if incremental:
            ctrl[0] = _clip(ctrl[0] + ai * cfg[C_DU], cfg[C_U_LO], cfg[C_U_HI])
        else:
            ctrl[0] = cfg[C_U_LO] + 0.5 * (ai + 1.0) * (cfg[C_U_HI] - cfg[C_U_LO])
        j = 1
    if mode != MODE_AMPLITUDE:
        ai = _clip(a[j], -1.0, 1.0)
        if incremental:
            ctrl[1] = _clip(ctrl[1] + ai * cfg[C_DNU], cfg[C_NU_LO], cfg[C_NU_HI])
        else:
            ctrl[1] = cfg[C_NU_LO] + 0.5 * (ai + 1.0) * (cfg[C_NU_HI] - cfg[C_NU_LO])


@kernel(inline=True)
def _method(P, cfg) -> int:
    m = int(cfg[C_METHOD])
    if m != METHOD_AUTO:
        return m
    if P[P_B1] == 0.0 and P[P_B3] == 0.0:
        return METHOD_EXACT
    return METHOD_EVENT


@kernel(inline=True)
def control_interval(P, S, ctrl, cfg, a, stats, res, work) -> int:
    """Apply action ``a``, advance one control interval, fill the reward terms in ``res``.

    Returns the core's status (non-zero: the interval failed and ``res`` is meaningless).
    """
    apply_action(ctrl, cfg, a)
    set_excitation(P, ctrl, cfg)
    dt = cfg[C_DT]
    x_start = S[S_X]
    reset_stats(stats)
    status = advance_ws(
        P, S, dt, stats, _method(P, cfg), cfg[C_RTOL], cfg[C_ATOL], int(cfg[C_MAX_EVENTS]), work
    )
    if status != 0:
        return status
    V = P[P_V]
    stick = _clip(stats[ST_STICK_TIME] / dt, 0.0, 1.0)
    # Variance of v - V over the interval: the mean of v is exactly (x_end - x_start) / dt.
    mean_vr = (S[S_X] - x_start) / dt - V
    var = stats[ST_VR2_INT] / dt - mean_vr * mean_vr
    if not var > 0.0:
        if math.isnan(var):  # the state is finite but its square overflowed
            return STATUS_NONFINITE
        var = 0.0
    fluct = var / (var + max(V * V, V2_FLOOR))
    effort = (P[P_U1] * P[P_U1] + P[P_U2] * P[P_U2]) * cfg[C_EFFORT_NORM]
    res[R_REWARD] = -(cfg[C_W_STICK] * stick + cfg[C_W_VEL] * fluct + cfg[C_W_EFFORT] * effort)
    res[R_STICK] = stick
    res[R_EFFORT] = effort
    res[R_VAR] = var
    res[R_MEAN_VR] = mean_vr
    return 0


@kernel(inline=True)
def _cos_sin(phi, work, key, c, s):
    """cos and sin of ``phi``, from the core's cache when it holds this very angle."""
    if phi == work[key]:
        return work[c], work[s]
    return math.cos(phi), math.sin(phi)


@kernel(inline=True)
def write_obs(P, S, ctrl, cfg, obs, work) -> bool:
    """Write the float32 observation; True when the state left the observation box.

    The tones' cos/sin come from the core's workspace when it holds them for the phases in
    ``S`` (the closed form carries them), which spares four transcendental calls a step.
    """
    x = S[S_X]
    vr = S[S_V] - P[P_V]
    xl = cfg[C_X_LIM]
    vl = cfg[C_V_LIM]
    c1, s1 = _cos_sin(S[S_PHI1], work, W_PH1, W_C1, W_S1)
    c2, s2 = _cos_sin(S[S_PHI2], work, W_PH2, W_C2, W_S2)
    obs[O_X] = _clip(x, -xl, xl)
    obs[O_VR] = _clip(vr, -vl, vl)
    obs[O_STICK] = 1.0 if S[S_MODE] == 0.0 else 0.0
    obs[O_COS1] = c1
    obs[O_SIN1] = s1
    obs[O_COS2] = c2
    obs[O_SIN2] = s2
    obs[O_U0] = ctrl[0]
    obs[O_NU] = ctrl[1]
    return abs(x) > xl or abs(vr) > vl


@kernel
def start_episode(P, S, ctrl, cfg, P_new, init, obs, work) -> None:
    """Begin an episode from a sampled parameter vector and starting vector."""
    for k in range(P.shape[0]):
        P[k] = P_new[k]
    ctrl[0] = init[I_U0]
    ctrl[1] = init[I_NU]
    set_excitation(P, ctrl, cfg)
    initial_state(P, init[I_X0], init[I_V0], S)
    S[S_PHI1] = init[I_PHI1]
    S[S_PHI2] = init[I_PHI2]
    # initial_state chose the mode with zero phases; redo it with the drawn ones.
    S[S_MODE] = initial_mode(P, S[S_X], S[S_V], S[S_PHI1], S[S_PHI2])
    write_obs(P, S, ctrl, cfg, obs, work)


@kernel(inline=True)
def _scaled(u, bounds, k):
    return bounds[0, k] + (bounds[1, k] - bounds[0, k]) * u[k]


@kernel
def episode_from_uniforms(u, bounds, cfg, P_out, init_out) -> None:
    """One episode's parameter and starting vectors from its N_DRAWS uniforms ``u``.

    ``bounds`` = [draw_lo, draw_hi]. This is ``EnvSetup.draw``'s scaling followed by
    ``scenes.episode_from_draws`` without options, operation for operation, so that an
    autoreset inside the step kernel starts exactly the episode a single environment's
    ``reset()`` would.
    """
    eta = _scaled(u, bounds, D_ETA)
    u0 = cfg[C_U0_START]
    nu = cfg[C_NU_START]
    P_out[P_LAM] = _scaled(u, bounds, D_LAM)
    P_out[P_V] = _scaled(u, bounds, D_V)
    P_out[P_XFK] = _scaled(u, bounds, D_XFK)
    P_out[P_XFS] = _scaled(u, bounds, D_XFS)
    P_out[P_B1] = _scaled(u, bounds, D_B1)
    P_out[P_B3] = _scaled(u, bounds, D_B3)
    P_out[P_W1] = eta
    P_out[P_U1] = cfg[C_G1] * u0
    P_out[P_U2] = cfg[C_G2] * u0
    P_out[P_W2] = nu * eta
    init_out[I_X0] = _scaled(u, bounds, D_X0)
    init_out[I_V0] = _scaled(u, bounds, D_V0)
    init_out[I_PHI1] = _scaled(u, bounds, D_PHI1) % TWO_PI
    init_out[I_PHI2] = _scaled(u, bounds, D_PHI2) % TWO_PI
    init_out[I_U0] = u0
    init_out[I_NU] = nu


@kernel
def step_single(P, S, ctrl, cfg, a, stats, obs, res, work) -> int:
    """One step of the single environment (one dispatch per step keeps it cheap)."""
    if not actions_finite(a):
        return STATUS_BAD_ACTION
    status = control_interval(P, S, ctrl, cfg, a, stats, res, work)
    if status != 0:
        return status
    res[R_TERM] = 1.0 if write_obs(P, S, ctrl, cfg, obs, work) else 0.0
    return 0


@kernel(inline=True)
def _plant_rows(table, i):
    """Plant ``i``'s parameters, state, excitation, stats and workspace: views of its row."""
    row = table[i]
    return (row[T_P:T_S], row[T_S:T_CTRL], row[T_CTRL:T_STATS], row[T_STATS:T_NEW_P],
            row[T_WORK:])


@kernel(inline=True)
def _plant_step(i, table, cfg, A, obs, res, flags, counters, max_steps, mode) -> int:
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
    status = control_interval(Pi, Si, ci, cfg, A[i], sti, res[:, i], wi)
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


@kernel
def _step_range(lo, hi, table, cfg, A, obs, res, flags, counters, draws, bounds, max_steps,
                mode) -> None:
    """Step plants ``lo`` to ``hi - 1`` (the body of both batch kernels).

    The per-plant body is inlined here: a call per plant would pass the batch's array
    structures each time, which measured as much as a sixth of a plant-step.
    """
    for i in range(lo, hi):
        counters[CT_STATUS, i] = _plant_step(i, table, cfg, A, obs, res, flags, counters,
                                             max_steps, mode)
        if flags[F_DID_RESET, i]:
            _start_next(i, table, cfg, obs, counters, draws, bounds)


@kernel
def step_batch(table, cfg, A, obs, res, flags, counters, draws, bounds, ivars) -> int:
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
    _step_range(0, table.shape[0], table, cfg, A, obs, res, flags, counters, draws, bounds,
                ivars[IV_MAX_STEPS], mode)
    return _count(flags, counters, draws.shape[1], ivars)


@kernel(inline=True)
def _region(worker, n_workers, n):
    """Plants [lo, hi) of the region that ``worker`` shares with its partner (workers 2r
    and 2r + 1 share region r; with an odd count the last worker has a region alone), sized
    by its number of workers so that every worker starts with an equal share."""
    first = worker - worker % 2
    return first * n // n_workers, min(first + 2, n_workers) * n // n_workers


@kernel(inline=True)
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


@kernel(inline=True)
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


@kernel(parallel=True)
def step_batch_parallel(table, cfg, A, obs, res, flags, counters, draws, bounds, ivars) -> int:
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
        _step_range(0, n, table, cfg, A, obs, res, flags, counters, draws, bounds, max_steps,
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
            _step_range(start, end, table, cfg, A, obs, res, flags, counters, draws, bounds,
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


@kernel(allocates=True)
def sample_interval(P, S, ctrl, cfg, a, stats, t_out, v_out, stick_out) -> int:
    """The coming interval's velocity at ``len(t_out)`` instants (the renderer's trace and
    ``StickSlipEnv.sample_interval``).

    Works on copies, so sampling never perturbs the dynamics of the real step.
    """
    Pc = P.copy()
    Sc = S.copy()
    cc = ctrl.copy()
    apply_action(cc, cfg, a)
    set_excitation(Pc, cc, cfg)
    n = t_out.shape[0]
    h = cfg[C_DT] / n
    m = _method(Pc, cfg)
    t0 = Sc[S_T]
    for k in range(n):
        reset_stats(stats)
        status = advance(Pc, Sc, h, stats, m, cfg[C_RTOL], cfg[C_ATOL], int(cfg[C_MAX_EVENTS]))
        if status != 0:
            return status
        t_out[k] = t0 + (k + 1) * h
        v_out[k] = Sc[S_V]
        stick_out[k] = Sc[S_MODE] == 0.0
    return 0


def empty_cfg() -> np.ndarray:
    return np.zeros(N_CFG)
