"""The vector environment's sensors and actuators: buffers for each of its plants.

``PlantInstruments`` is what ``StickSlipVectorEnv`` (``fricenv.envs.vector``) owns when it
is made with sensor or actuator options (``fricenv.envs.sensors``): the delay lines, noise
streams and actuator commands of its plants, which a step moves around the kernel call,
and their part of a plant's saved state. It is handed the plants' arrays it reads and
writes, and reads nothing else.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from fricenv.envs import kernels as K
from fricenv.envs.batch import first_bad_action
from fricenv.envs.sensors import InstrumentBank, actuate_batch
from fricenv.envs.setup import EnvSetup, raise_status
from fricenv.envs.state import PlantState


class PlantInstruments:
    """Sensor and actuator buffers of ``n`` plants made with ``setup`` (which has
    instruments)."""

    def __init__(self, setup: EnvSetup, n: int):
        inst = setup.instruments
        if inst is None:
            raise ValueError("PlantInstruments needs a setup with sensor or actuator options")
        full = setup.full_observation_space
        self.bank = InstrumentBank(inst, n, full.low, full.high)
        #: whether the observation is the sensors' reading, and whether an actuator
        #: stands between the action and the applied setting
        self.sensing = inst.sensing
        self.actuating = inst.actuating
        self._ucfg = setup.cfg  # the configuration the actions are scaled with
        self._all_plants = np.arange(n)
        #: the sensors' readings of the episodes that ended on the last step (same-step
        #: autoreset: the infos' final_obs)
        self.final_sensed = np.zeros((n, setup.observation_space.shape[0]), dtype=np.float32)
        self._act = inst.actuator_params(setup.cfg) if inst.actuating else None
        self._zero_actions = np.zeros((n, *setup.action_space.shape))

    # -- around a step -------------------------------------------------------------------------
    def actuate(self, a: np.ndarray, ctrl: np.ndarray, autoreset: np.ndarray,
                mode: int) -> np.ndarray:
        """Move every stepped plant's command and applied setting ``ctrl`` by its action
        (checked first, as the kernel would; a plant ``autoreset`` marks for a restart
        ignores its action, autoreset ``mode`` as the kernel's); returns the zero actions
        the kernel then gets."""
        assert self._act is not None  # (called only when actuating)
        bad = first_bad_action(a, autoreset, mode)
        if bad >= 0:
            raise_status(K.STATUS_BAD_ACTION, a[bad], f" {bad}")
        actuate_batch(ctrl, self.bank.cmd, self._ucfg, a, self._act, autoreset)
        return self._zero_actions

    def start(self, idx: np.ndarray, rngs: list[np.random.Generator | None], ctrl: np.ndarray,
              obs: np.ndarray, scale: np.ndarray, lag: np.ndarray) -> None:
        """Plants ``idx`` start episodes: noise streams spawned from their generators
        ``rngs[i]``, commands at their start settings ``ctrl``, noise scales and delays
        from the reset options ``scale``, ``lag`` (one per plant of ``idx``;
        ``sensors.NO_SCALE``, ``NO_DELAY``: not given), first readings ``obs``."""
        bank = self.bank
        for i in idx.tolist():
            bank.seed_noise(i, rngs[i])
        bank.cmd[idx] = ctrl[idx]
        bank.start(idx, obs[idx], scale, lag)

    def after_step(self, obs: np.ndarray, final_obs: np.ndarray | None, ctrl: np.ndarray,
                   did_reset: np.ndarray | None) -> np.ndarray:
        """After the kernel: the sensors read the plants' observations ``obs`` (an ended
        episode's last one, ``final_obs``, first when given: same-step autoreset), the
        plants ``did_reset`` marks (None: none) start afresh with their commands at their
        start settings ``ctrl``; returns the observations."""
        bank = self.bank
        if did_reset is None:
            if self.sensing:
                bank.push(self._all_plants, obs)
        else:
            restarted = np.flatnonzero(did_reset)
            stepped = np.flatnonzero(~did_reset)
            if self.sensing:
                if final_obs is not None:
                    bank.push(restarted, final_obs[restarted])
                    self.final_sensed[restarted] = bank.output(restarted)
                bank.push(stepped, obs[stepped])
                bank.start(restarted, obs[restarted])
            bank.cmd[restarted] = ctrl[restarted]
        return self.observation(obs)

    def observation(self, obs: np.ndarray) -> np.ndarray:
        """What the agents observe of the exact observations ``obs``: the sensors'
        readings, or a copy of ``obs`` when only an actuator is set."""
        return self.bank.output() if self.sensing else obs.copy()

    def reading(self, i: int, obs: np.ndarray) -> np.ndarray:
        """Plant ``i``'s observation (``observation`` for one plant)."""
        return self.bank.output(np.array([i]))[0] if self.sensing else obs[i].copy()

    # -- plant state ---------------------------------------------------------------------------
    @property
    def delay_rows(self) -> int | None:
        """Rows of a plant's delay line (None: no delay line)."""
        delay = self.bank.delay
        return None if delay is None else delay.shape[1]

    @property
    def noisy(self) -> bool:
        """Whether the plants have noise streams (noise, or the sensors' randomisation)."""
        return self.bank.normals is not None

    def commands(self, ctrl: np.ndarray) -> np.ndarray:
        """Every plant's command (the applied settings ``ctrl`` without an actuator)."""
        return self.bank.cmd if self.actuating else ctrl

    def state_of(self, i: int, ctrl: np.ndarray) -> dict[str, Any]:
        """Plant ``i``'s command, delay line, noise stream, noise scale and delay
        (``PlantState``'s fields by name, copies)."""
        bank = self.bank
        sensing = bank.delay is not None
        return {"command": self.commands(ctrl)[i].copy(),
                "delay": bank.delay[i].copy() if bank.delay is not None else None,
                "noise": bank.noise_state(i),
                "noise_scale": float(bank.scale[i]) if sensing else 1.0,
                "obs_delay": int(bank.lag[i]) if sensing else None}

    def restore(self, i: int, state: PlantState) -> None:
        """Put plant ``i``'s command, delay line and noise stream as in ``state`` (checked
        by ``state.check_state`` against ``delay_rows`` and ``noisy``)."""
        bank = self.bank
        bank.cmd[i] = state.command
        if bank.delay is not None:
            bank.delay[i] = state.delay
            bank.restore_sensors(i, state.noise_scale, state.obs_delay)
        bank.set_noise_state(i, state.noise)
