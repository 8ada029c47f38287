"""Gymnasium environments for stick-slip suppression (single and natively vectorised).

``register_envs()`` (called by ``import fricenv``) registers one id per scene, each with the
scene's horizon as ``max_episode_steps`` (as Gymnasium does for ``FrozenLake8x8``):

=================================  ==============  =================
id                                 scene           max_episode_steps
=================================  ==============  =================
``fricenv/StickSlip-v0``           ``paper``       200
``fricenv/StickSlipSelfExcited-v0``  ``self_excited``  400
``fricenv/StickSlipStribeck-v0``   ``stribeck``    300
``fricenv/StickSlipViscous-v0``    ``viscous``     300
=================================  ==============  =================

Registration imports Gymnasium's registry alone: the environments' classes, and numba
with them, load on the first ``make`` (``tests/test_imports.py`` checks it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from fricenv.envs.ids import ENV_IDS, HORIZONS, env_id_of

if TYPE_CHECKING:
    from fricenv.envs.settings import EnvKwargs, EnvSettings

__all__ = [
    "ENV_IDS",
    "EnvKwargs",
    "EnvSettings",
    "HORIZONS",
    "SCENES",
    "Scene",
    "StickSlipEnv",
    "StickSlipSB3VecEnv",
    "StickSlipVectorEnv",
    "env_id_of",
    "register_envs",
]


def register_envs() -> None:
    """Register the environments with Gymnasium (idempotent)."""
    from gymnasium.envs.registration import register, registry

    for env_id, scene in ENV_IDS.items():
        if env_id in registry:
            continue
        register(
            id=env_id,
            entry_point="fricenv.envs.stick_slip:StickSlipEnv",
            vector_entry_point="fricenv.envs.vector:StickSlipVectorEnv",
            max_episode_steps=HORIZONS[scene],
            kwargs={"scene": scene},
        )


def __getattr__(name: str) -> Any:  # lazy exports keep ``import fricenv`` light
    if name in ("EnvKwargs", "EnvSettings"):
        from fricenv.envs import settings

        return getattr(settings, name)
    if name in ("SCENES", "Scene"):
        from fricenv.envs import scenes

        return getattr(scenes, name)
    if name == "StickSlipEnv":
        from fricenv.envs.stick_slip import StickSlipEnv

        return StickSlipEnv
    if name == "StickSlipVectorEnv":
        from fricenv.envs.vector import StickSlipVectorEnv

        return StickSlipVectorEnv
    if name == "StickSlipSB3VecEnv":
        from fricenv.envs.sb3 import StickSlipSB3VecEnv

        return StickSlipSB3VecEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
