"""Batch rollouts: K action sequences of H control intervals from saved plant states, in
one numba call.

This is the exact plant as a model for planning (``fricenv_agents.mpc``): each sample copies a
start plant vector (``fricenv.envs.state``) into its own row and steps it through its
actions with the environments' own per-interval kernel (``kernels.control_interval``,
and the actuator of ``fricenv.envs.sensors`` when the env has one), built on the core
method its plants need (``fricenv.envs.steppers``), so a sample's rewards
and stick fractions are bit for bit those the environment would return for the same
actions from that state. Samples run on numba threads (``prange``: each writes only its
own rows), so the result is the same for any thread count. The sensors are not modelled:
a rollout scores the plant, as the reward does.

A sample ends early if its interval fails (its status is the core's code) or its state
leaves the observation box (the env would terminate the episode there); rewards and stick
fractions after its last interval are 0.

The kernels take the rollout's inputs and buffers as two records (:class:`RolloutJob`,
:class:`RolloutBuffers`); the body is written once over the core's entry kernel and
``fricenv.core.partial_kernel`` builds each method's kernels from it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numba import prange

from fricenv.checks import check_bool, check_int, got
from fricenv.core import partial_kernel
from fricenv.envs import kernels as K
from fricenv.envs.kernels import Plant
from fricenv.envs.sensors import actuate, no_actuator
from fricenv.envs.state import N_PLANT, PL_CTRL, PL_P, PL_S, PL_WORK, PlantState
from fricenv.envs.steppers import Steppers, steppers_for_plants
from fricenv.jit import kernel, parallel_section
from fricenv.layout import N_STATS, S_V, S_X
from fricenv.params import P_V

#: Most samples and intervals one rollout object is made for (its buffers are
#: samples x horizon floats a few times over).
MAX_SAMPLES = 1 << 20
MAX_HORIZON = 1 << 16
#: Status of a sample whose state left the observation box (the core's codes are > 0).
STATUS_LEFT_BOX = -2


class RolloutJob(NamedTuple):
    """What a batch rollout starts from and runs: ``plants`` (M, N_PLANT) start plant
    vectors and ``cmds`` (M, 2) their actuator commands; ``src`` (K,) int64, the start row
    of each sample; ``cfg``, the kernels' configuration (incremental when ``actuated``);
    ``ucfg``, the env's own (maps actions to commands); ``act``, the actuator's parameters
    (``sensors.A_*``); ``A`` (K, H, n_act) float64 actions; ``actuated``: whether actions
    go through the actuator."""

    plants: np.ndarray
    cmds: np.ndarray
    src: np.ndarray
    cfg: np.ndarray
    ucfg: np.ndarray
    act: np.ndarray
    A: np.ndarray
    actuated: bool


class RolloutBuffers(NamedTuple):
    """A batch rollout's scratch, one row per sample: ``table`` (K, N_PLANT), ``cmd``
    (K, 2), ``stats`` (K, N_STATS), ``res`` (K, N_RES); ``zero`` (n_act,) zeros, the
    kernels' action with an actuator. Its outputs: ``rewards`` and ``stick`` (K, H),
    ``length`` and ``status`` (K,) int64."""

    table: np.ndarray
    cmd: np.ndarray
    stats: np.ndarray
    res: np.ndarray
    zero: np.ndarray
    rewards: np.ndarray
    stick: np.ndarray
    length: np.ndarray
    status: np.ndarray


@kernel
def _left_box(P, S, cfg) -> bool:
    """The env's termination test (``kernels.write_obs``) on the state alone."""
    return abs(S[S_X]) > cfg[K.C_X_LIM] or abs(S[S_V] - P[P_V]) > cfg[K.C_V_LIM]


@kernel(called_once=True)
def _start_sample(k, job, buf):
    """Copy sample ``k``'s start plant and command into its rows; zero its outputs."""
    row = buf.table[k]
    s = job.src[k]
    for j in range(row.shape[0]):
        row[j] = job.plants[s, j]
    buf.cmd[k, 0] = job.cmds[s, 0]
    buf.cmd[k, 1] = job.cmds[s, 1]
    buf.status[k] = 0
    buf.length[k] = job.A.shape[1]
    for h in range(job.A.shape[1]):
        buf.rewards[k, h] = 0.0
        buf.stick[k, h] = 0.0


@kernel(takes_kernels=True)
def _sample_with(advance_ws, k, job, buf) -> None:
    """Roll sample ``k`` of the :class:`RolloutJob` ``job`` out by the core's entry kernel
    ``advance_ws``, in its rows of the :class:`RolloutBuffers` ``buf`` (the body of the
    rollout kernels)."""
    _start_sample(k, job, buf)
    row = buf.table[k]
    cmd = buf.cmd[k]
    res = buf.res[k]
    plant = Plant(row[PL_P:PL_S], row[PL_S:PL_CTRL], row[PL_CTRL:PL_WORK], buf.stats[k],
                  row[PL_WORK:])
    cfg = job.cfg
    for h in range(job.A.shape[1]):
        if job.actuated:
            actuate(plant.ctrl, cmd, job.ucfg, job.A[k, h], job.act)
            code = K.control_interval(advance_ws, plant, cfg, buf.zero, res)
        else:
            code = K.control_interval(advance_ws, plant, cfg, job.A[k, h], res)
        if code != 0:
            buf.status[k] = code
            buf.length[k] = h
            return
        buf.rewards[k, h] = res[K.R_REWARD]
        buf.stick[k, h] = res[K.R_STICK]
        if _left_box(plant.P, plant.S, cfg):
            buf.status[k] = STATUS_LEFT_BOX
            buf.length[k] = h + 1
            return


@kernel(takes_kernels=True)
def _rollout_with(sample, job, buf) -> None:
    """Roll every sample out with ``sample`` (a ``_sample_with`` of its own), in parallel.

    ``job`` and ``buf``: a :class:`RolloutJob` and :class:`RolloutBuffers`, as plain tuples
    (numba types a plain tuple of arrays from Python from its fingerprint, a named one
    field by field in Python: 6 us more per call). They are named here, before the loop,
    by their classes (numba's parallel lowering rebuilds a record the loop uses by the
    name of the call that made it)."""
    named_job = RolloutJob(*job)
    named_buf = RolloutBuffers(*buf)
    for k in prange(named_job.A.shape[0]):
        sample(k, named_job, named_buf)


@kernel(takes_kernels=True)
def _serial_with(sample, job, buf) -> None:
    """``_rollout_with`` on the calling thread (for callers that run plants in threads of
    their own, and for timing one core)."""
    named_job = RolloutJob(*job)
    named_buf = RolloutBuffers(*buf)
    for k in range(named_job.A.shape[0]):
        sample(k, named_job, named_buf)


#: The (parallel, serial) rollout kernels made so far, by ``Steppers.name``.
_KERNELS: dict[str, tuple[Any, Any]] = {}


def _rollout_kernels(steppers: Steppers) -> tuple[Any, Any]:
    """The (parallel, serial) rollout kernels built on the core's entry kernel of
    ``steppers``: a rollout of Coulomb plants compiles no Taylor code. Each sample runs a
    kernel of its own (``_sample_<name>``), compiled once and called by both."""
    made = _KERNELS.get(steppers.name)
    if made is None:
        name = steppers.name
        sample = partial_kernel(_sample_with, steppers.advance_ws, f"_sample_{name}")
        made = _KERNELS[name] = (
            partial_kernel(_rollout_with, sample, f"_rollout_{name}", parallel=True),
            partial_kernel(_serial_with, sample, f"_serial_{name}"))
    return made


@dataclass(frozen=True)
class RolloutResult:
    """What a batch rollout returns (arrays over samples; see the module docstring).

    ``rewards`` and ``stick_fraction`` (K, H): per interval; ``length`` (K,): intervals
    completed; ``status`` (K,): 0, ``STATUS_LEFT_BOX`` or the core's failure code.
    """

    rewards: np.ndarray
    stick_fraction: np.ndarray
    length: np.ndarray
    status: np.ndarray

    @property
    def returns(self) -> np.ndarray:
        """Each sample's summed reward."""
        return self.rewards.sum(axis=1)


def _setup_of(env: Any) -> Any:
    """The ``EnvSetup`` of an environment (single, vector, SB3 adapter, wrapped) or itself."""
    for obj in (env, getattr(env, "unwrapped", None), getattr(env, "venv", None)):
        setup = getattr(obj, "setup", None)
        if setup is not None and hasattr(setup, "kernel_cfg"):
            return setup
    if hasattr(env, "kernel_cfg") and hasattr(env, "cfg"):
        return env
    raise TypeError(f"env must be a fricenv environment (or its EnvSetup), {got(env)}")


class BatchRollout:
    """Roll out ``n_samples`` action sequences of ``horizon`` intervals on ``env``'s plant
    model, reusing its buffers from call to call.

    ``env``: a ``StickSlipEnv`` (wrapped or not), ``StickSlipVectorEnv``, SB3 adapter or
    their ``EnvSetup``: its configuration (control interval, ranges, reward, action mode,
    actuator) is the model's. ``parallel``: samples on numba's threads.
    """

    def __init__(self, env: Any, n_samples: int, horizon: int, parallel: bool = True):
        setup = _setup_of(env)
        self.n_samples = check_int("n_samples", n_samples, 1, MAX_SAMPLES)
        self.horizon = check_int("horizon", horizon, 1, MAX_HORIZON)
        self.parallel = check_bool("parallel", parallel)
        inst = setup.instruments
        self.actuated = inst is not None and inst.actuating
        self.cfg = setup.kernel_cfg
        self.ucfg = setup.cfg
        self.act = inst.actuator_params(setup.cfg) if self.actuated else no_actuator()
        self.n_act = setup.action_space.shape[0]
        k, h = self.n_samples, self.horizon
        self._buf = RolloutBuffers(
            table=np.zeros((k, N_PLANT)), cmd=np.zeros((k, 2)), stats=np.zeros((k, N_STATS)),
            res=np.zeros((k, K.N_RES)), zero=np.zeros(self.n_act), rewards=np.zeros((k, h)),
            stick=np.zeros((k, h)), length=np.zeros(k, dtype=np.int64),
            status=np.zeros(k, dtype=np.int64))
        self._buf_fields = tuple(self._buf)
        self._src0 = np.zeros(k, dtype=np.int64)

    def run(self, start: PlantState | tuple[np.ndarray, np.ndarray], actions: np.ndarray,
            sources: np.ndarray | None = None) -> RolloutResult:
        """Roll out ``actions`` (n_samples, horizon, n_act), normalised as the env's, from
        ``start``: a ``PlantState``, or ``(plants, commands)`` arrays (M, N_PLANT) and
        (M, 2) (``StickSlipVectorEnv.state_arrays()``) with ``sources`` (n_samples,) naming
        each sample's start row. The result's arrays are this object's buffers, overwritten
        by the next call (copy what you keep)."""
        plants, cmds = self._starts(start)
        if sources is None:
            if plants.shape[0] != 1:
                raise ValueError(f"{plants.shape[0]} start states need sources, one start "
                                 "row per sample")
            src = self._src0
        else:
            src = np.asarray(sources)
            if src.shape != (self.n_samples,) or src.dtype.kind not in "iu":
                raise ValueError(f"sources must be {self.n_samples} integers, {got(sources)}")
            if src.size and (src.min() < 0 or src.max() >= plants.shape[0]):
                raise ValueError(f"sources must lie in [0, {plants.shape[0]}), got values "
                                 f"{src.min()}..{src.max()}")
            src = np.ascontiguousarray(src, dtype=np.int64)
        A = self._actions(actions)
        steppers = steppers_for_plants(self.cfg[K.C_METHOD], plants[:, PL_P:PL_S])
        run = _rollout_kernels(steppers)[0 if self.parallel else 1]
        # a RolloutJob's and the RolloutBuffers' fields as plain tuples (see _rollout_with)
        job = (plants, cmds, src, self.cfg, self.ucfg, self.act, A, self.actuated)
        with parallel_section(self.parallel):
            run(job, self._buf_fields)
        buf = self._buf
        return RolloutResult(buf.rewards, buf.stick, buf.length, buf.status)

    def end_states(self) -> tuple[np.ndarray, np.ndarray]:
        """The plant vectors (n_samples, N_PLANT) and actuator commands (n_samples, 2) each
        sample ended in at the last ``run``: a state estimator steps its particles this way
        (horizon 1), exactly as the environment steps its plants. A sample that failed holds
        the state its failing interval left. These are this object's buffers, overwritten by
        the next call (copy what you keep). Without an actuator the command is the applied
        setting, as in ``StickSlipVectorEnv.state_arrays()``."""
        buf = self._buf
        if not self.actuated:  # (the kernels moved the setting in the table only)
            buf.cmd[:] = buf.table[:, PL_CTRL:PL_WORK]
        return buf.table, buf.cmd

    def _starts(self, start: Any) -> tuple[np.ndarray, np.ndarray]:
        if isinstance(start, PlantState):
            return start.plant[None, :], start.command[None, :]
        if isinstance(start, tuple) and len(start) == 2:
            plants, cmds = start
            ok = (isinstance(plants, np.ndarray) and plants.ndim == 2
                  and plants.shape[1] == N_PLANT and plants.dtype == np.float64
                  and isinstance(cmds, np.ndarray) and cmds.shape == (plants.shape[0], 2)
                  and cmds.dtype == np.float64)
            if ok:
                return plants, cmds
        raise TypeError("start must be a PlantState or (plants, commands) float64 arrays of "
                        f"shapes (M, {N_PLANT}) and (M, 2), {got(start)}")

    def _actions(self, actions: Any) -> np.ndarray:
        want = (self.n_samples, self.horizon, self.n_act)
        a = np.asarray(actions)
        if a.shape != want or a.dtype.kind != "f":
            raise ValueError(f"actions must be a float array of shape {want}, {got(actions)}")
        a = np.ascontiguousarray(a, dtype=np.float64)  # (float32 -> float64 is exact)
        if not np.all(np.isfinite(a)):
            raise ValueError("actions must be finite (no NaN or inf)")
        return a


def rollout_batch(env: Any, state: PlantState, actions: np.ndarray,
                  parallel: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Rewards and stick fractions (K, H) of the K action sequences ``actions`` (K, H,
    n_act) from ``state`` (``env.get_state()``) on ``env``'s plant model; ``RuntimeError``
    if an interval fails. For repeated calls, keep a ``BatchRollout``."""
    a = np.asarray(actions)
    if a.ndim != 3:
        raise ValueError(f"actions must have shape (K, H, n_act), got shape {a.shape}")
    result = BatchRollout(env, a.shape[0], a.shape[1], parallel).run(state, a)
    failed = np.flatnonzero(result.status > 0)
    if failed.size:
        raise RuntimeError(f"sample {int(failed[0])}: the plant's integration failed with "
                           f"status {int(result.status[failed[0]])} at interval "
                           f"{int(result.length[failed[0]])}")
    return result.rewards.copy(), result.stick_fraction.copy()
