"""The vector environment's instruments and its per-plant state API.

``VectorPlants`` is a mixin of ``StickSlipVectorEnv`` (``fricenv.envs.vector``): the
sensor and actuator buffers of its plants (``fricenv.envs.sensors``), which a step moves
around the kernel call, and ``get_state`` / ``set_state`` / ``state_arrays``, which read
and write one plant or all of them between steps. Kept apart from the stepping and
resetting so that each module holds one concern; the attributes it reads are the vector
env's own, declared below for the type checker.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import error as gym_error
from gymnasium.vector import AutoresetMode

from fricenv.checks import check_int
from fricenv.envs import kernels as K
from fricenv.envs.batch import first_bad_action
from fricenv.envs.scenes import Scene
from fricenv.envs.sensors import InstrumentBank, actuate_batch
from fricenv.envs.setup import EnvSetup, raise_status
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
from fricenv.layout import S_MODE, S_T, S_V

if TYPE_CHECKING:
    from fricenv.envs.rendering import Trace


class VectorPlants:
    """Instruments and per-plant state of ``StickSlipVectorEnv`` (see the module docstring)."""

    # set by StickSlipVectorEnv.__init__ (and _bind_views: views of the kernels' arrays)
    setup: EnvSetup
    scene: Scene
    num_envs: int
    dt: float
    _cfg: np.ndarray
    _ivars: np.ndarray
    _autoreset_mode: AutoresetMode
    _needs_reset: bool
    _P: np.ndarray
    _S: np.ndarray
    _ctrl: np.ndarray
    _work: np.ndarray
    _obs: np.ndarray
    _final_obs: np.ndarray
    _terminated: np.ndarray
    _truncated: np.ndarray
    _autoreset: np.ndarray
    _did_reset: np.ndarray
    _steps: np.ndarray
    _traces: list[Trace] | None
    # set by _init_instruments
    _bank: InstrumentBank | None  # the sensors' and actuators' buffers, if any
    _act: np.ndarray | None  # the actuator's parameters, if any
    _sensing: bool
    _all_plants: np.ndarray
    _final_sensed: np.ndarray
    _zero_actions: np.ndarray

    if TYPE_CHECKING:
        def _fit_steppers(self) -> None: ...

        def _check_cost(self, P: np.ndarray, u0: float, nu: float, what: str) -> None: ...

    # -- instruments ---------------------------------------------------------------------------
    def _init_instruments(self, n: int) -> None:
        """Buffers of the sensor and actuator options (``fricenv.envs.sensors``), if any."""
        inst = self.setup.instruments
        self._bank = None
        self._act = None
        self._sensing = False
        if inst is None:
            return
        full = self.setup.full_observation_space
        self._bank = InstrumentBank(inst, n, full.low, full.high)
        self._sensing = inst.sensing
        self._all_plants = np.arange(n)
        if inst.sensing:
            self._final_sensed = np.zeros((n, self.setup.observation_space.shape[0]),
                                          dtype=np.float32)
        if inst.actuating:
            self._act = inst.actuator_params(self.setup.cfg)
            self._zero_actions = np.zeros((n, *self.setup.action_space.shape))

    def _actuate(self, a: np.ndarray) -> np.ndarray:
        """Move every stepped plant's actuator command and output by its action (checked
        first, as the kernel would); the kernel then gets zero actions."""
        bank = self._bank
        assert bank is not None  # an actuator (self._act) comes with its buffers
        bad = first_bad_action(a, self._autoreset, self._ivars[K.IV_MODE])
        if bad >= 0:
            raise_status(K.STATUS_BAD_ACTION, a[bad], f" {bad}")
        # (a plant the kernel resets instead of stepping ignores its action)
        actuate_batch(self._ctrl, bank.cmd, self.setup.cfg, a, self._act, self._autoreset)
        return self._zero_actions

    def _instruments_after_step(self) -> np.ndarray:
        """After the kernel: the sensors read the plants (an ended episode's last state
        first, then the new episode's start), restarted plants' commands are their start
        settings; returns the observations."""
        bank, did = self._bank, self._did_reset
        assert bank is not None  # called only for an env with instruments
        if self._ivars[K.IV_N_RESET] == 0:
            if self._sensing:
                bank.push(self._all_plants, self._obs)
        else:
            restarted = np.flatnonzero(did)
            stepped = np.flatnonzero(~did)
            if self._sensing:
                if self._autoreset_mode is AutoresetMode.SAME_STEP:
                    bank.push(restarted, self._final_obs[restarted])
                    self._final_sensed[restarted] = bank.output(restarted)
                bank.push(stepped, self._obs[stepped])
                bank.start(restarted, self._obs[restarted])
            bank.cmd[restarted] = self._ctrl[restarted]
        return self._observation()

    def _observation(self) -> np.ndarray:
        """What the agents observe now: the exact observations, or the sensors' readings."""
        bank = self._bank
        return bank.output() if bank is not None and self._sensing else self._obs.copy()

    # -- plant state ---------------------------------------------------------------------------
    def _plant_index(self, i: Any) -> int:
        if self._needs_reset:
            raise gym_error.ResetNeeded("reset the vector env before reading or setting a "
                                        "plant's state")
        return check_int("plant index i", i, 0, self.num_envs - 1)

    def get_state(self, i: int) -> PlantState:
        """Plant ``i``'s full state (``fricenv.envs.state.PlantState``)."""
        i = self._plant_index(i)
        bank = self._bank
        # (a bank has a delay line exactly when it senses, a command apart from the applied
        # setting exactly when it actuates)
        command = self._ctrl[i] if bank is None or self._act is None else bank.cmd[i]
        return PlantState(
            pack(self._P[i], self._S[i], self._ctrl[i], self._work[i]),
            command.copy(),
            None if bank is None or bank.delay is None else bank.delay[i].copy(),
            None if bank is None else bank.noise_state(i),
            int(self._steps[i]),
        )

    def set_state(self, i: int, state: PlantState) -> np.ndarray:
        """Put plant ``i`` in ``state`` (from ``get_state`` of an environment made with the
        same arguments, single or vector) and return its observation. Its episode goes on
        from there: an ending pending for the next step is cancelled, and its step count
        (for truncation) is the state's. A plant too costly to step among ``num_envs`` is
        refused (``ValueError``), as reset options are."""
        i = self._plant_index(i)
        bank = self._bank
        check_state(state, None if bank is None or bank.delay is None else bank.delay.shape[1],
                    bank is not None and bank.normals is not None, self.scene.u0_range,
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
        if bank is not None:
            bank.cmd[i] = state.command
            if bank.delay is not None:
                bank.delay[i] = state.delay
            bank.set_noise_state(i, state.noise)
        if self._traces is not None:
            self._traces[i].clear(self._S[i, S_T], self._S[i, S_V], self._S[i, S_MODE] == 0)
        if bank is not None and self._sensing:
            return bank.output(np.array([i]))[0]
        return self._obs[i].copy()

    def state_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Every plant's plant vector (n, N_PLANT) and actuator command (n, 2), copied in two
        arrays: the fast way to plan from all plants at once (``fricenv.envs.rollout``)."""
        if self._needs_reset:
            raise gym_error.ResetNeeded("reset the vector env before reading plant states")
        plants = np.empty((self.num_envs, N_PLANT))
        for i in range(self.num_envs):
            pack(self._P[i], self._S[i], self._ctrl[i], self._work[i], plants[i])
        bank = self._bank
        commands = (self._ctrl if bank is None or self._act is None else bank.cmd).copy()
        return plants, commands
