"""Warm-starting a policy from the exact-model MPC: DAgger through the plant-state API.

An on-policy learner from scratch finds the steady state of the self-excited scenes
quickly (excite a little, or not at all, once the block slides), but the transient that
quenches the stick-slip from a random start lasts a few dozen control intervals, and its
credit assignment is where PPO stays behind the MPC. The MPC (``fricenv_agents.mpc``)
reads the exact plant states of the training environment (``state_arrays``), so it can
label any state the learner visits with the action it would take. DAgger (Ross, Gordon and
Bagnell, AISTATS 2011) uses that: round 0 drives the plants with the MPC, every later round
with the current policy, and each round's states, labelled by the MPC, join one data set
on which the policy's mean action is fitted (mean squared error in the normalised action
box). The critic is then fitted to the normalised discounted returns of the last round,
and the policy's exploration noise set to ``log_std``, so that PPO's fine-tuning starts
from the imitation rather than from a random policy with unit noise.

The rounds step the training environment itself, through its ``VecNormalize`` wrapper
in training mode, so the observation and return statistics PPO starts with are those of
the plants the imitation saw; they count as environment steps of the run
(``config.yml`` records them), though not as PPO's timesteps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

#: Settings of a warm start, as the hyperparameter file's ``warm_start`` mapping gives them.
WARM_START_KEYS = ("rounds", "epochs", "batch_size", "learning_rate", "log_std", "value_epochs",
                   "steps")


@dataclass(frozen=True)
class WarmStart:
    """DAgger settings (see the module docstring).

    ``rounds``: rounds of one full episode per plant each (round 0 driven by the MPC);
    ``epochs``: passes over the aggregated data per round; ``batch_size`` and
    ``learning_rate``: of the Adam fit; ``log_std``: the policy's exploration noise
    afterwards (natural log of the standard deviation in normalised action units);
    ``value_epochs``: passes of the critic's fit on the last round's returns; ``steps``:
    control intervals per plant and round, from the episodes' starts (``None``: the whole
    training episode). Fewer steps put the labels, and the MPC's compute, on the start of
    the episodes, where the quench of the stick-slip costs most (the critic's targets are
    then cut at the round's end: PPO's fine-tuning corrects them).
    """

    rounds: int = 6
    epochs: int = 10
    batch_size: int = 256
    learning_rate: float = 1e-3
    log_std: float = -1.5
    value_epochs: int = 10
    steps: int | None = None

    @classmethod
    def from_mapping(cls, value: Any) -> WarmStart:
        """The ``warm_start`` entry of a hyperparameter file, checked."""
        if not isinstance(value, dict):
            raise ValueError(f"warm_start must be a mapping of {WARM_START_KEYS}, got "
                             f"{value!r}")
        unknown = sorted(set(value) - set(WARM_START_KEYS))
        if unknown:
            raise ValueError(f"warm_start: unknown key(s) {unknown}; expected some of "
                             f"{WARM_START_KEYS}")
        out = cls(**value)
        for key in ("rounds", "epochs", "batch_size", "value_epochs"):
            v = getattr(out, key)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"warm_start.{key} must be an int >= 1, got {v!r}")
        if out.steps is not None and (isinstance(out.steps, bool)
                                      or not isinstance(out.steps, int) or out.steps < 1):
            raise ValueError(f"warm_start.steps must be an int >= 1 or null, got "
                             f"{out.steps!r}")
        for key in ("learning_rate", "log_std"):
            v = getattr(out, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise ValueError(f"warm_start.{key} must be a finite number, got {v!r}")
        if out.learning_rate <= 0:
            raise ValueError(f"warm_start.learning_rate must be > 0, got {out.learning_rate!r}")
        return out

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in WARM_START_KEYS}


def _plant_env(venv: Any) -> Any:
    """The fricenv vector env under SB3's wrappers (VecNormalize, VecMonitor, the adapter)."""
    env = venv
    while not hasattr(env, "state_arrays"):
        inner = getattr(env, "venv", None)
        if inner is None:
            raise TypeError(f"no fricenv vector env under {type(venv).__name__}")
        env = inner
    return env


def _collect(model: Any, venv: Any, expert: Any, steps: int,
             by_expert: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One round: ``steps`` steps of every plant, driven by the expert or by the policy's
    mean action. Returns the raw observations and the expert's actions (steps * n, ...), and
    the normalised rewards and episode ends (steps, n) for the critic's targets."""
    n = venv.num_envs
    obs_norm = venv.reset()
    raw = venv.get_original_obs()
    start = np.ones(n, dtype=bool)
    n_act = venv.action_space.shape[0]
    obs_out = np.empty((steps, n, raw.shape[1]), dtype=np.float32)
    act_out = np.empty((steps, n, n_act), dtype=np.float32)
    rew = np.empty((steps, n))
    done = np.empty((steps, n), dtype=bool)
    for t in range(steps):
        label, _ = expert.predict(raw, None, start)
        obs_out[t], act_out[t] = raw, label
        if by_expert:
            action = label
        else:
            action, _ = model.predict(obs_norm, deterministic=True)
        obs_norm, r, d, _ = venv.step(np.asarray(action, dtype=np.float32))
        raw = venv.get_original_obs()
        rew[t], done[t] = r, d
        start = d
    return (obs_out.reshape(steps * n, -1), act_out.reshape(steps * n, -1), rew, done)


def _discounted(rew: np.ndarray, done: np.ndarray, gamma: float) -> np.ndarray:
    """Discounted returns to go of every step, cut at episode ends (steps, n)."""
    out = np.empty_like(rew)
    acc = np.zeros(rew.shape[1])
    for t in range(rew.shape[0] - 1, -1, -1):
        acc = rew[t] + gamma * acc * ~done[t]
        out[t] = acc
    return out


def _fit(params: list, loss_of: Any, inputs: Any, targets: Any, settings: WarmStart,
         epochs: int, rng: np.random.Generator) -> float:
    """Adam over minibatches of (``inputs``, ``targets``) rows for ``epochs`` passes; the
    last epoch's mean loss. ``loss_of(x, y)`` returns the loss tensor of a minibatch."""
    import torch

    opt = torch.optim.Adam(params, lr=settings.learning_rate)
    n = len(inputs)
    last = float("nan")
    for _ in range(epochs):
        order = rng.permutation(n)
        total = 0.0
        for lo in range(0, n, settings.batch_size):
            idx = order[lo:lo + settings.batch_size]
            loss = loss_of(inputs[idx], targets[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach()) * idx.size
        last = total / n
    return last


def dagger(model: Any, venv: Any, scene: str, env_kwargs: dict[str, Any],
           settings: WarmStart, seed: int, log: Any = None) -> dict[str, Any]:
    """Warm-start ``model`` (an SB3 on-policy actor-critic, e.g. PPO) on ``venv`` (its
    training env, normalised or not) from the MPC; returns a summary for ``config.yml``."""
    import torch

    from .mpc import MPPIController  # (numba kernels: loaded only when a warm start runs)

    plants = _plant_env(venv)
    episode = int(plants.max_episode_steps)
    if settings.steps is not None and settings.steps > episode:
        raise ValueError(f"warm_start.steps ({settings.steps}) exceeds the training "
                         f"episodes' {episode} intervals")
    steps = episode if settings.steps is None else settings.steps
    expert = MPPIController(scene, env_kwargs, seed=seed)
    expert.bind(plants)
    policy = model.policy
    rng = np.random.default_rng(seed)
    gamma = float(getattr(model, "gamma", 0.99))
    normalize = getattr(venv, "normalize_obs", None)

    def actor_loss(x: Any, y: Any) -> Any:
        return torch.mean((policy.get_distribution(x).distribution.mean - y) ** 2)

    obs_sets: list[np.ndarray] = []
    act_sets: list[np.ndarray] = []
    losses = []
    rew = done = None
    for r in range(settings.rounds):
        o, a, rew, done = _collect(model, venv, expert, steps, by_expert=r == 0)
        obs_sets.append(o)
        act_sets.append(a)
        obs = np.concatenate(obs_sets)
        obs_t = torch.as_tensor(normalize(obs) if normalize else obs, dtype=torch.float32)
        act_t = torch.as_tensor(np.concatenate(act_sets))
        losses.append(_fit(list(policy.parameters()), actor_loss, obs_t, act_t, settings,
                           settings.epochs, rng))
        if log is not None:
            log(f"warm start round {r + 1}/{settings.rounds}: {len(obs_t)} labels, "
                f"imitation loss {losses[-1]:.4f}, return per plant over the round "
                f"{float(np.sum(rew) / rew.shape[1]):.3f} (normalised)")
    assert rew is not None and done is not None
    returns = torch.as_tensor(_discounted(rew, done, gamma).reshape(-1, 1),
                              dtype=torch.float32)
    last_obs = obs_sets[-1]
    last_t = torch.as_tensor(normalize(last_obs) if normalize else last_obs,
                             dtype=torch.float32)

    def value_loss(x: Any, y: Any) -> Any:
        return torch.mean((policy.predict_values(x) - y) ** 2)

    value = _fit(list(policy.parameters()), value_loss, last_t, returns, settings,
                 settings.value_epochs, rng)
    with torch.no_grad():
        policy.log_std.fill_(settings.log_std)
    expert.bind(None)
    return {**settings.as_dict(), "env_steps": settings.rounds * steps * venv.num_envs,
            "imitation_loss": [round(x, 6) for x in losses], "value_loss": round(value, 6)}
