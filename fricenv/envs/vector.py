"""Native vector environment: N stick-slip plants stepped by one numba call, with autoreset.

Built like Gymnasium's ``CartPoleVectorEnv`` but bit-compatible with
``SyncVectorEnv`` over ``StickSlipEnv``: plant ``i`` owns its own random generator, seeded
``seed + i`` as ``SyncVectorEnv`` seeds its sub-environments, and the kernel autoresets it
in place with exactly the numbers a single environment would draw at its next ``reset()``
(buffered ahead, ``fricenv.envs.vector_draws``). The environment owns its parts rather
than inheriting them: the random streams (``PlantDraws``), the sensors and actuators
(``fricenv.envs.vector_instruments.PlantInstruments``) and the frames
(``fricenv.envs.vector_render.PlantFrames``), each handed the arrays it works on.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Unpack

import numpy as np
from gymnasium import error as gym_error
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from fricenv.checks import check_dict, check_int, got, is_int, items_of
from fricenv.core import new_workspace
from fricenv.envs import kernels as K
from fricenv.envs.batch import TASKS_PER_THREAD, first_bad_action, start_batch
from fricenv.envs.scenes import N_INIT, check_episode_cost
from fricenv.envs.sensors import NO_DELAY, NO_SCALE, split_sensor_options
from fricenv.envs.settings import EnvKwargs, EnvSettings, settings_signature
from fricenv.envs.setup import ACTION_DTYPES, EnvSetup, coerce_action, raise_status
from fricenv.envs.state import (
    N_PLANT,
    PL_CTRL,
    PL_P,
    PL_S,
    PL_WORK,
    PlantState,
    check_state,
    pack,
    unpack,
)
from fricenv.envs.steppers import Steppers, steppers_for_plants
from fricenv.envs.stick_slip import RenderModes, check_render_mode
from fricenv.envs.vector_draws import (
    DRAW_ROWS,
    PlantDraws,
    named_plant,
    plant_options,
    plant_seeds,
)
from fricenv.envs.vector_instruments import PlantInstruments
from fricenv.envs.vector_render import PlantFrames, plant_snapshot
from fricenv.friction import polynomial_laws_in
from fricenv.jit import num_threads, parallel_section
from fricenv.layout import METHOD_EXACT, STATUS_DIVERGED

_AUTORESET = {
    AutoresetMode.NEXT_STEP: K.AUTORESET_NEXT_STEP,
    AutoresetMode.SAME_STEP: K.AUTORESET_SAME_STEP,
    AutoresetMode.DISABLED: K.AUTORESET_DISABLED,
}
#: Info keys, in the order of their rows in the kernel's results (adjacent: one slice
#: takes them all), and their masks' keys.
_INFO_KEYS = ("stick_fraction", "effort", "velocity_variance", "mean_relative_velocity")
_MASK_KEYS = tuple("_" + key for key in _INFO_KEYS)
_INFO_ROWS = slice(K.R_STICK, K.R_MEAN_VR + 1)
# The reward's row and the info rows, adjacent too: a step copies them in one go.
_OUT_ROWS = slice(K.R_REWARD, K.R_MEAN_VR + 1)
assert K.R_REWARD + 1 == K.R_STICK
# terminated and truncated: adjacent rows of the flags, copied in one go as well.
_END_ROWS = slice(K.F_TERMINATED, K.F_TRUNCATED + 1)
assert K.F_TERMINATED + 1 == K.F_TRUNCATED
assert K.N_INIT == N_INIT
# Spelled out for the step's common case (a dict display and plain indexing cost a third of
# a loop over the keys, which measured ~1 us a step).
_K0, _K1, _K2, _K3 = _INFO_KEYS
_M0, _M1, _M2, _M3 = _MASK_KEYS


def _info_dict(vals, masks) -> dict[str, Any]:
    """SyncVectorEnv's layout of the infos: each key's values, then its ``_key`` mask
    (``vals`` and ``masks``: one array per key, in ``_INFO_KEYS`` order)."""
    infos: dict[str, Any] = {}
    for key, mask_key, val, mask in zip(_INFO_KEYS, _MASK_KEYS, vals, masks, strict=True):
        infos[key] = val
        infos[mask_key] = mask
    return infos


#: Most plants a vector env may hold: about 7 kB each (the kernels' table, buffered draws
#: and a random generator), 700 MB at the cap and some ten seconds to build and seed them.
MAX_NUM_ENVS = 10**5
#: Most scan steps (``core.most_scan_steps``, the kernels' own floor) one vector step may
#: need over all its plants: about a second at the closed form's ~90 ns a step. Each plant
#: is held to ``scenes.MAX_INTERVAL_SCAN_STEPS`` already; this bounds their sum (10,000
#: plants under a tone at eta = 1e5 would take minutes a step).
MAX_VECTOR_SCAN_STEPS = 1e7
#: From this many plants on, a step spreads them over threads (numba prange).
PARALLEL_MIN_ENVS = 64


def _check_max_steps(value: Any) -> int:
    """An episode length the kernel's int64 step counters can hold."""
    return check_int("max_episode_steps", value, 1, int(np.iinfo(np.int64).max))


class StickSlipVectorEnv(VectorEnv):
    """``num_envs`` independent ``StickSlipEnv`` plants, stepped in one numba call.

    Arguments are those of ``StickSlipEnv`` (the settings, ``EnvSettings``' fields as
    keywords or one record as ``settings=``, and ``render_mode``) plus ``num_envs`` (1 to
    ``MAX_NUM_ENVS``, and few enough that a step needs at most ``MAX_VECTOR_SCAN_STEPS``
    scan steps in all), ``max_episode_steps`` (default: the scene's horizon;
    ``gymnasium.make_vec`` passes the registered one) and ``autoreset_mode``
    (``AutoresetMode`` or its value; default next-step, as Gymnasium's).
    Observations ``(num_envs, 9)`` float32, actions ``(num_envs, n)`` in [-1, 1], rewards
    float64, and ``info`` keys ``stick_fraction``, ``effort``, ``velocity_variance``,
    ``mean_relative_velocity`` with their ``_key`` masks, as ``SyncVectorEnv`` would batch
    them (same-step mode adds ``final_obs`` and ``final_info``). One difference: on a step
    where every plant reports, the masks are one shared read-only all-True array, which
    spares a copy per key. ``render_mode="rgb_array"`` returns one frame per plant.
    """

    metadata = {
        "render_modes": RenderModes(["rgb_array"]),
        "render_fps": 12,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    @settings_signature
    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        *,
        settings: EnvSettings | None = None,
        **kwargs: Unpack[EnvKwargs],
    ):
        # first: close() runs from __del__ even when a check below refuses the arguments
        self._frames: PlantFrames | None = None  # each plant's recent motion, if rendering
        num_envs = check_int("num_envs", num_envs, 1, MAX_NUM_ENVS)
        check_render_mode(render_mode, self.metadata["render_modes"])
        self._autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = {**type(self).metadata, "autoreset_mode": self._autoreset_mode}
        self.setup = EnvSetup.build(EnvSettings.of(settings, kwargs, "StickSlipVectorEnv"))
        self.scene = self.setup.scene
        self.scene.check_interval_cost(self.setup.randomize, MAX_VECTOR_SCAN_STEPS / num_envs,
                                       self._batch_context(num_envs))
        self.num_envs = n = num_envs
        max_episode_steps = _check_max_steps(
            self.scene.max_episode_steps if max_episode_steps is None else max_episode_steps
        )
        self.render_mode = render_mode
        self.dt = self.scene.control_dt

        self.single_action_space = self.setup.action_space
        self.action_space = batch_space(self.single_action_space, n)
        self.single_observation_space = self.setup.observation_space
        self.observation_space = batch_space(self.single_observation_space, n)

        self._cfg = self.setup.kernel_cfg
        # the sensors' and actuators' buffers, if any
        self._inst = None if self.setup.instruments is None else PlantInstruments(self.setup, n)
        # The kernels' few batch arrays (kernels.T_* and friends); the per-plant arrays the
        # Python side works with are views of them (_bind_views).
        self._table = np.zeros((n, K.N_TABLE))
        self._obs_pair = np.zeros((2, n, K.N_OBS), dtype=np.float32)
        self._res = np.zeros((K.N_RES, n))  # a row per result (contiguous copies)
        self._flags = np.zeros((K.N_FLAGS, n), dtype=np.bool_)
        self._counters = np.zeros((K.N_COUNTERS, n), dtype=np.int64)
        self._bind_views()
        self._work[:] = new_workspace(n, extrema=False)
        self._ivars = np.zeros(K.N_IVARS, dtype=np.int64)
        self._ivars[K.IV_MAX_STEPS] = max_episode_steps
        self._ivars[K.IV_MODE] = _AUTORESET[self._autoreset_mode]

        # Each plant's generator and buffered uniforms (the kernel reads _draws, the same
        # array), and its next row.
        self._streams = PlantDraws(n)
        self._draws = self._streams.draws
        self._cursor[:] = DRAW_ROWS
        self._bounds = np.stack([self.setup.draw_lo, self.setup.draw_hi])
        self._use_steppers(steppers_for_plants(self._cfg[K.C_METHOD],
                                               self.setup.scene.params.to_array(),
                                               *self._bounds))
        # Episodes started in the kernel skip EnvSetup.episode's check: it cannot fail
        # without options when b1 and b3 are drawn from [0, 0].
        b1, b3 = (tuple(self._bounds[:, k]) for k in (K.D_B1, K.D_B3))
        if self._cfg[K.C_METHOD] == METHOD_EXACT and "cubic" in polynomial_laws_in(b1, b3):
            raise ValueError("method='exact' needs the Coulomb law (b1 = b3 = 0)")
        self._act_shape = (n, *self.single_action_space.shape)
        self._needs_reset = True
        self._failed_plant: int | None = None  # the plant whose failure needs a full reset
        # The info mask when every plant reports: shared by the keys and the steps, so
        # read-only (a caller that keeps it cannot have it changed under them).
        self._all_true = np.ones(n, dtype=np.bool_)
        self._all_true.flags.writeable = False

        if render_mode is not None:
            self._frames = PlantFrames(n, self.dt)

    def _use_steppers(self, steppers: Steppers) -> None:
        """Step with the entry kernels ``steppers`` (see ``steppers_for_plants``): threads
        pay off from a few dozen plants; both kernels give identical results."""
        self._steppers = steppers
        self._serial_kernel = steppers.step_batch
        parallel = self.num_envs >= PARALLEL_MIN_ENVS
        self._step_kernel = steppers.step_batch_parallel if parallel else steppers.step_batch
        self._ivars[K.IV_N_TASKS] = TASKS_PER_THREAD * num_threads()

    def _fit_steppers(self) -> None:
        """The entry kernels of the plants now in the table (after resets with options, or
        a restored state) and of the episodes the draws can start."""
        steppers = steppers_for_plants(self._cfg[K.C_METHOD], self._table[:, K.T_P:K.T_S],
                                       *self._bounds)
        if steppers is not self._steppers:
            self._use_steppers(steppers)

    @staticmethod
    def _batch_context(n: int) -> str:
        return (f"a vector step runs it for each of num_envs = {n} plants, at most "
                f"MAX_VECTOR_SCAN_STEPS = {MAX_VECTOR_SCAN_STEPS:g} scan steps in all (use "
                "fewer plants); ")

    def _bind_views(self) -> None:
        """Make the per-plant arrays the Python side reads: views of the kernels' batch
        arrays (after a copy or unpickling too, where views come back as arrays of their
        own and would no longer see what the kernels write)."""
        t = self._table
        self._P = t[:, K.T_P : K.T_S]
        self._S = t[:, K.T_S : K.T_CTRL]
        self._ctrl = t[:, K.T_CTRL : K.T_STATS]
        self._stats = t[:, K.T_STATS : K.T_NEW_P]
        # the episode being started is built in _new_P, _new_init
        self._new_P = t[:, K.T_NEW_P : K.T_NEW_INIT]
        self._new_init = t[:, K.T_NEW_INIT : K.T_WORK]
        self._work = t[:, K.T_WORK :]  # core cache kept across intervals
        self._obs = self._obs_pair[K.OB_NOW]
        self._final_obs = self._obs_pair[K.OB_FINAL]
        self._terminated = self._flags[K.F_TERMINATED]
        self._truncated = self._flags[K.F_TRUNCATED]
        self._autoreset = self._flags[K.F_AUTORESET]
        self._did_reset = self._flags[K.F_DID_RESET]
        # what a step returns is copied from these views, made once (a slice costs as much)
        self._step_out = self._res[_OUT_ROWS]
        self._step_ends = self._flags[_END_ROWS]
        self._steps = self._counters[K.CT_STEPS]
        self._cursor = self._counters[K.CT_CURSOR]
        self._status = self._counters[K.CT_STATUS]

    def __setstate__(self, state: dict[str, Any]) -> None:
        # copy.deepcopy and pickle restore every view as an array of its own, and every
        # array writable: the infos' shared mask must stay read-only in a copy too
        self.__dict__.update(state)
        self._bind_views()
        self._all_true.flags.writeable = False

    # VectorEnv's is one int; a seed per plant is what SyncVectorEnv reports for its envs
    @property
    def np_random_seed(self) -> tuple[int | None, ...]:  # type: ignore[override]
        """Each plant's seed, as ``SyncVectorEnv`` reports its envs' (``seed + i`` or
        ``seed[i]``, a random one where a plant was first reset with None; None before a
        plant's first reset)."""
        return tuple(self._streams.seeds)

    @property
    def settings(self) -> EnvSettings:
        """The settings this environment was made with."""
        return self.setup.settings

    @property
    def max_episode_steps(self) -> int:
        """Steps after which an episode is truncated; may be changed between steps (an
        episode already that long is truncated at the next step)."""
        return int(self._ivars[K.IV_MAX_STEPS])

    @max_episode_steps.setter
    def max_episode_steps(self, value: int) -> None:
        self._ivars[K.IV_MAX_STEPS] = _check_max_steps(value)

    @property
    def autoreset_mode(self) -> AutoresetMode:
        """How ended episodes restart; fixed at construction (the kernel's and the
        infos' layout follow it)."""
        return self._autoreset_mode

    # -- Gymnasium VectorEnv API -----------------------------------------------------------
    def reset(
        self,
        *,
        seed: int | list[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset all plants (or those in ``options["reset_mask"]``), seeding plant i with
        ``seed + i`` (or ``seed[i]``). Another option applies to every reset plant, or, as
        a numpy array of shape ``(num_envs,)``, gives plant i its element i (checked as a
        scalar would be; with ``reset_mask``, the masked plants' elements are used)."""
        n = self.num_envs
        seeds = plant_seeds(seed, n)
        check_dict("options", options)
        options = dict(options) if options else {}
        if "reset_mask" not in options:
            mask = np.ones(n, dtype=np.bool_)
        else:
            mask = options.pop("reset_mask")
            if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_:
                raise TypeError(
                    f"options['reset_mask'] must be a numpy bool array, {got(mask)}"
                )
            if mask.shape != (n,):
                raise ValueError(
                    f"options['reset_mask'] must have shape ({n},), got shape {mask.shape}"
                )
            if not mask.any():
                raise ValueError("options['reset_mask'] must select at least one plant")
            if self._needs_reset and not mask.all():
                if self._failed_plant is not None:
                    raise ValueError(
                        f"after the failed step (plant {self._failed_plant}) every plant "
                        "must be reset: that step moved the other plants too, and its "
                        "results were never returned"
                    )
                raise ValueError("the first reset must reset every plant")
        idx = np.flatnonzero(mask)
        per_plant = plant_options(options, n)
        self._reset_plants(idx, [seeds[i] for i in idx.tolist()],
                           [options] * idx.size if per_plant is None
                           else [per_plant[i] for i in idx.tolist()], per_plant is not None)
        if is_int(seed):  # (after every check: a rejected reset reseeds nothing)
            super().reset(seed=int(seed))
        return self._observation(), {}

    def reset_plants(
        self, seeds: Sequence[int | None], options: Sequence[Mapping[str, Any] | None]
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Reset every plant, plant ``i`` seeded ``seeds[i]`` (None: its generator goes on)
        and with the reset options ``options[i]`` (a dict as ``reset``'s, without
        ``reset_mask``, or None), as SB3's ``VecEnv.seed`` and ``set_options`` ask; returns
        what ``reset`` does. A value of ``options[i]`` that is a numpy array of shape
        ``(num_envs,)`` gives plant i its element i (so ``set_options`` of one dict of
        arrays sweeps the plants). A refused option leaves every plant as it was."""
        n = self.num_envs
        each_seed = plant_seeds(seeds, n)
        opts = items_of(options)
        if opts is None:
            raise TypeError(f"options must be a list of num_envs={n} dicts or Nones, "
                            f"{got(options)}")
        if len(opts) != n:
            raise ValueError(f"options must have length num_envs={n}, got {len(opts)}: "
                             f"{options!r}")
        for i, opt in enumerate(opts):
            check_dict(f"options[{i}]", opt)
            if opt and "reset_mask" in opt:
                raise ValueError(f"options[{i}] holds 'reset_mask': reset_plants resets every "
                                 "plant (reset(options={'reset_mask': m}) resets some)")
        each_options = []
        for i, opt in enumerate(opts):
            with named_plant(i):
                per_plant = plant_options(opt, n) if opt else None
            each_options.append(per_plant[i] if per_plant is not None
                                else dict(opt) if opt else {})
        self._reset_plants(np.arange(n), each_seed, each_options, True)
        return self._observation(), {}

    def _reset_plants(self, idx: np.ndarray, seeds: list, options: list[dict],
                      name_plants: bool = False) -> None:
        """Start new episodes for plants ``idx``, validating ``options`` per plant (an error
        names the plant with ``name_plants``); a rejected reset loses nothing
        (``PlantDraws.start_episodes``; the sensors' options are all checked before)."""
        inst = self.setup.instruments
        scale = np.full(idx.size, NO_SCALE)
        lag = np.full(idx.size, NO_DELAY, dtype=np.int64)
        rest = []
        for j, (i, opt) in enumerate(zip(idx.tolist(), options, strict=True)):
            with named_plant(i, name_plants):
                others, scale[j], lag[j] = split_sensor_options(opt, inst)
            rest.append(others or {})
        mask = self._streams.start_episodes(idx, seeds, rest, self._cursor, self.setup,
                                            self._new_P, self._new_init,
                                            self._check_batch_cost, name_plants)
        start_batch(self._table, self._cfg, mask, self._obs_pair, self._flags, self._counters)
        # options may have given the plants another law or damping than the draws' bounds
        self._fit_steppers()
        if self._inst is not None:
            self._inst.start(idx, self._streams.rngs, self._ctrl, self._obs, scale, lag)
        self._terminated[mask] = False
        self._truncated[mask] = False
        self._needs_reset = False
        self._failed_plant = None
        self._refill_empty()
        if self._frames is not None:
            self._frames.clear(idx, self._S)

    def _check_batch_cost(self, plants: list[int]) -> None:
        """``ValueError`` unless the new episodes of ``plants`` (started with reset options)
        keep a vector step within ``MAX_VECTOR_SCAN_STEPS``; episodes drawn without options
        stay within what the constructor checked."""
        if not plants:
            return
        starts = self._new_init[plants][:, [K.I_U0, K.I_NU]]
        for u0, nu in np.unique(starts, axis=0).tolist():
            same = np.array(plants)[np.all(starts == (u0, nu), axis=1)]
            self._check_cost(self._new_P[same], u0, nu, "change the reset options")

    def _check_cost(self, P: np.ndarray, u0: float, nu: float, what: str) -> None:
        """``ValueError`` (its message ending in ``what``) unless plants ``P`` under the
        setting ``(u0, nu)`` keep a vector step within ``MAX_VECTOR_SCAN_STEPS``."""
        check_episode_cost(self.scene, P, u0, nu, self._batch_context(self.num_envs) + what,
                           MAX_VECTOR_SCAN_STEPS / self.num_envs)

    def _refill_empty(self) -> None:
        self._streams.refill_empty(self._cursor)

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if self._needs_reset:
            if self._failed_plant is not None:
                raise gym_error.ResetNeeded(
                    f"the last step failed (plant {self._failed_plant}); reset every plant "
                    "before stepping again"
                )
            raise gym_error.ResetNeeded("Cannot call step() before calling reset()")
        if self._autoreset_mode is AutoresetMode.DISABLED and self._autoreset.any():
            # SyncVectorEnv asserts this mid-step; here it is refused before any plant moves
            ended = np.flatnonzero(self._autoreset).tolist()
            raise gym_error.ResetNeeded(
                f"plants {ended} ended their episodes and autoreset is disabled: reset them "
                "(options={'reset_mask': mask}) before the next step"
            )
        a = actions
        if (
            type(a) is not np.ndarray
            or a.shape != self._act_shape
            or a.dtype not in ACTION_DTYPES
            or not a.flags.c_contiguous
        ):
            a = coerce_action(actions, self._act_shape, "actions", batch=True)
        inst = self._inst
        if inst is not None and inst.actuating:
            a = inst.actuate(a, self._ctrl, self._autoreset, self._ivars[K.IV_MODE])
        if self._frames is not None:
            self._record_frames(a)
        kernel = self._step_kernel
        with parallel_section(kernel is not self._serial_kernel):
            n_failed = kernel(
                self._table,
                self._cfg,
                a,
                self._obs_pair,
                self._res,
                self._flags,
                self._counters,
                self._draws,
                self._bounds,
                self._ivars,
            )
        if n_failed != 0:
            if n_failed < 0:
                i = -n_failed - 1
                raise_status(K.STATUS_BAD_ACTION, a[i], f" {i}")
            self._needs_reset = True
            i = int(np.flatnonzero(self._status)[0])
            self._failed_plant = i
            raise_status(int(self._status[i]), None, f" {i}")
        rewards = self._step_out[K.R_REWARD]  # NaN where (v - V)^2 overflowed (see
        if math.isnan(rewards @ rewards):      # StickSlipEnv.step); the sensors stay as they were
            self._needs_reset = True
            i = int(np.flatnonzero(np.isnan(rewards))[0])
            self._failed_plant = i
            raise_status(STATUS_DIVERGED, None, f" {i}")
        # (the sensors first: the infos below carry their readings of ended episodes)
        obs = self._obs.copy() if inst is None else self._instruments_after_step(inst)
        out = self._step_out.copy()  # callers may keep what a step returns
        if self._ivars[K.IV_N_RESET] == 0:
            # The common case: every plant reports this step's values (_info_dict's layout).
            m = self._all_true
            infos = {_K0: out[1], _M0: m, _K1: out[2], _M1: m, _K2: out[3], _M2: m,
                     _K3: out[4], _M3: m}
        else:
            infos = self._after_resets()
        ends = self._step_ends.copy()
        return obs, out[K.R_REWARD], ends[0], ends[1], infos

    def _after_resets(self) -> dict[str, Any]:
        """After a step that reset plants: refill spent buffers, restart traces, and batch
        the infos as SyncVectorEnv would (a plant reset now reports its empty reset info)."""
        if self._ivars[K.IV_N_EMPTY]:
            self._refill_empty()
        done = self._did_reset.copy()
        if self._frames is not None:
            self._frames.clear(np.flatnonzero(done), self._S)
        vals = self._res[_INFO_ROWS]
        infos: dict[str, Any] = {}
        if self._ivars[K.IV_N_RESET] < self.num_envs:
            has = ~done
            now = np.where(has, vals, 0.0)
            infos.update(_info_dict(now, np.broadcast_to(has, now.shape).copy()))
        if self.autoreset_mode == AutoresetMode.SAME_STEP:
            final_obs = np.full(self.num_envs, None, dtype=object)
            inst = self._inst
            finals = inst.final_sensed if inst is not None and inst.sensing else self._final_obs
            for i in np.flatnonzero(done).tolist():
                final_obs[i] = finals[i].copy()
            fin = np.where(done, vals, 0.0)
            infos["final_obs"] = final_obs
            infos["_final_obs"] = done.copy()
            infos["final_info"] = _info_dict(fin, np.broadcast_to(done, fin.shape).copy())
            infos["_final_info"] = done
        return infos

    def _record_frames(self, a: np.ndarray) -> None:
        """Extend the plants' traces by the coming interval, every action checked before
        any trace moves (the kernel checks them too)."""
        frames = self._frames
        assert frames is not None  # called only when rendering
        bad = first_bad_action(a, self._autoreset, self._ivars[K.IV_MODE])
        if bad >= 0:
            raise_status(K.STATUS_BAD_ACTION, a[bad], f" {bad}")
        # a plant the step restarts instead of stepping (next-step mode) keeps its trace
        skip = self._autoreset if self._autoreset_mode == AutoresetMode.NEXT_STEP else None
        plants = K.Plant(self._P, self._S, self._ctrl, self._stats, self._work)
        frames.record(self._steppers, plants, self._cfg, a, skip)

    def _instruments_after_step(self, inst: PlantInstruments) -> np.ndarray:
        """The sensors read what the kernel left (``PlantInstruments.after_step``)."""
        if self._ivars[K.IV_N_RESET] == 0:
            return inst.after_step(self._obs, None, self._ctrl, None)
        same_step = self._autoreset_mode is AutoresetMode.SAME_STEP
        return inst.after_step(self._obs, self._final_obs if same_step else None, self._ctrl,
                               self._did_reset)

    def _observation(self) -> np.ndarray:
        """What the agents observe now: the exact observations, or the sensors' readings."""
        inst = self._inst
        return self._obs.copy() if inst is None else inst.observation(self._obs)

    # -- rendering -------------------------------------------------------------------------
    def render(self) -> tuple[np.ndarray, ...] | None:
        """One ``rgb_array`` frame per plant (None, with a warning, without render_mode)."""
        if self._frames is None:
            from gymnasium import logger

            logger.warn(
                "You are calling render method without specifying any render mode. "
                "You can specify the render_mode at initialization, e.g. "
                'gym.make_vec("fricenv/StickSlip-v0", render_mode="rgb_array") '
                'or StickSlipVectorEnv(render_mode="rgb_array")'
            )
            return None
        return self._frames.draw([self.snapshot(i) for i in range(self.num_envs)])

    def close_extras(self, **kwargs: Any) -> None:
        if self._frames is not None:
            self._frames.close()

    def snapshot(self, i: int) -> dict[str, float]:
        """What a frame draws of plant ``i``: state, excitation and force now."""
        return plant_snapshot(self._P[i], self._S[i], self._ctrl[i], self.scene.x_limit)

    # -- plant state -----------------------------------------------------------------------
    def _plant_index(self, i: Any) -> int:
        if self._needs_reset:
            raise gym_error.ResetNeeded("reset the vector env before reading or setting a "
                                        "plant's state")
        return check_int("plant index i", i, 0, self.num_envs - 1)

    def get_state(self, i: int) -> PlantState:
        """Plant ``i``'s full state (``fricenv.envs.state.PlantState``)."""
        i = self._plant_index(i)
        plant = pack(self._P[i], self._S[i], self._ctrl[i], self._work[i])
        steps = int(self._steps[i])
        if self._inst is None:
            return PlantState(plant, self._ctrl[i].copy(), None, None, steps)
        return PlantState(plant, episode_steps=steps, **self._inst.state_of(i, self._ctrl))

    def set_state(self, i: int, state: PlantState) -> np.ndarray:
        """Put plant ``i`` in ``state`` (from ``get_state`` of an environment made with the
        same arguments, single or vector) and return its observation. Its episode goes on
        from there: an ending pending for the next step is cancelled, and its step count
        (for truncation) is the state's. A plant too costly to step among ``num_envs`` is
        refused (``ValueError``), as reset options are."""
        i = self._plant_index(i)
        inst = self._inst
        check_state(state, None if inst is None else inst.delay_rows,
                    inst is not None and inst.noisy, self.scene.u0_range,
                    self.scene.nu_range, self.dt)
        u0, nu = state.plant[PL_CTRL:PL_WORK].tolist()
        self._check_cost(state.plant[PL_P:PL_S], u0, nu,
                         "refused state: its plant is too stiff or too fast")
        unpack(state.plant, self._P[i], self._S[i], self._ctrl[i], self._work[i])
        self._fit_steppers()  # (the state's plant may have another damping or law)
        K.write_obs(self._P[i], self._S[i], self._ctrl[i], self._cfg, self._obs[i],
                    self._work[i])
        self._steps[i] = state.episode_steps
        self._autoreset[i] = self._terminated[i] = self._truncated[i] = False
        if inst is not None:
            inst.restore(i, state)
        if self._frames is not None:
            self._frames.clear([i], self._S)
        return self._obs[i].copy() if inst is None else inst.reading(i, self._obs)

    def state_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Every plant's plant vector (n, N_PLANT) and actuator command (n, 2), copied in two
        arrays: the fast way to plan from all plants at once (``fricenv.envs.rollout``)."""
        if self._needs_reset:
            raise gym_error.ResetNeeded("reset the vector env before reading plant states")
        plants = np.empty((self.num_envs, N_PLANT))
        for i in range(self.num_envs):
            pack(self._P[i], self._S[i], self._ctrl[i], self._work[i], plants[i])
        ctrl = self._ctrl
        return plants, (ctrl if self._inst is None else self._inst.commands(ctrl)).copy()
