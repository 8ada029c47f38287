"""The environments' Gymnasium ids and horizons: what registering them needs, kept apart
from :mod:`fricenv.envs.scenes` (which imports the kernels) so that ``import fricenv``
registers the ids without loading numba."""

from __future__ import annotations

#: Registered ids and the scene each one makes.
ENV_IDS: dict[str, str] = {
    "fricenv/StickSlip-v0": "paper",
    "fricenv/StickSlipSelfExcited-v0": "self_excited",
    "fricenv/StickSlipStribeck-v0": "stribeck",
    "fricenv/StickSlipViscous-v0": "viscous",
    "fricenv/StickSlipExponential-v0": "exponential",
}
#: Each scene's horizon: the ``max_episode_steps`` of its id and of its ``Scene``.
HORIZONS: dict[str, int] = {"paper": 200, "self_excited": 400, "stribeck": 300, "viscous": 300,
                            "exponential": 300}


def env_id_of(scene: str) -> str:
    """The registered id of a scene (``KeyError`` naming it and the scenes otherwise)."""
    for env_id, name in ENV_IDS.items():
        if name == scene:
            return env_id
    raise KeyError(f"no registered environment for scene {scene!r}; scenes: "
                   f"{sorted(ENV_IDS.values())}")
