"""Names and the seed layout that training, evaluation and the baselines share.

Evaluation episodes must never be ones an agent trained on, and two controllers run with
the same seed must face the same episodes; the blocks of plant seeds below make both hold.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import fricenv  # noqa: F401  (registers the environments)
from fricenv.envs import HORIZONS, env_id_of

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

#: Scene name -> registered Gymnasium id (the key of the hyperparameter files).
SCENE_ENV_IDS: dict[str, str] = {scene: env_id_of(scene) for scene in HORIZONS}
ALGOS = ("ppo", "sac")
#: The baseline controllers, by name (built by ``baselines.make_baseline``).
BASELINES = ("zero", "random", "best_constant", "feedback")


# -- seed layout ----------------------------------------------------------------------------
# Plant i of a vector environment seeded s draws from seed s + i. The blocks below never
# overlap, so no evaluation episode is one a policy (or the best-constant search) saw.
SEED_STRIDE = 1000  #: seeds reserved per training seed / evaluation seed
MAX_PLANTS = SEED_STRIDE // 2  #: plants per block (training and in-training evaluation)
EVAL_SEED_BASE = 10_000_000  #: final evaluation: seed k, episode j -> base + 1000 k + j
SEARCH_SEED_BASE = 20_000_000  #: best-constant search episodes
MAX_TRAIN_SEED = EVAL_SEED_BASE // SEED_STRIDE  # training seeds stay below the eval block


def train_env_seed(seed: int) -> int:
    """First plant seed of the training environment of run ``seed``."""
    return SEED_STRIDE * seed


def callback_env_seed(seed: int) -> int:
    """First plant seed of the periodic evaluation during training (not the final one)."""
    return SEED_STRIDE * seed + MAX_PLANTS


def eval_env_seed(k: int) -> int:
    """First plant seed of final-evaluation seed ``k``."""
    return EVAL_SEED_BASE + SEED_STRIDE * k


def check_seed(seed: int) -> int:
    """``seed`` as an int if it is a training seed (below the evaluation block)."""
    if isinstance(seed, bool) or int(seed) != seed or not 0 <= seed < MAX_TRAIN_SEED:
        raise ValueError(f"seed must be an integer in [0, {MAX_TRAIN_SEED}), got {seed!r}")
    return int(seed)


def eval_seeds(n_seeds: int, episodes: int) -> list[int]:
    """All plant seeds of the final evaluation."""
    return [eval_env_seed(k) + j for k in range(n_seeds) for j in range(episodes)]


def check_disjoint(config: dict, n_seeds: int, episodes: int, where: str) -> None:
    """Refuse to evaluate on any episode the run trained or was monitored on."""
    used: list[tuple[int, int]] = []
    for key in ("train_env_seeds", "eval_callback_seeds"):
        if key in config:
            lo, hi = config[key]
            used.append((int(lo), int(hi)))
    for s in eval_seeds(n_seeds, episodes):
        for lo, hi in used:
            if lo <= s <= hi:
                raise ValueError(f"{where}: evaluation seed {s} was used in training ({lo}-{hi})")


# -- names ----------------------------------------------------------------------------------
def check_scene(scene: str) -> str:
    """``scene`` if it names a scene, else a ``ValueError`` listing them."""
    if scene not in HORIZONS:  # (the scenes' names, without loading the scenes' kernels)
        raise ValueError(f"unknown scene {scene!r}; expected one of {sorted(HORIZONS)}")
    return scene


def check_algo(algo: str) -> str:
    """``algo`` if it is a supported algorithm, else a ``ValueError`` listing them."""
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {algo!r}; expected one of {list(ALGOS)}")
    return algo


def algo_class(algo: str) -> type[BaseAlgorithm]:
    """The SB3 class of ``algo`` (imports torch: call it only when training or loading)."""
    from stable_baselines3 import PPO, SAC

    classes: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "sac": SAC}
    return classes[check_algo(algo)]


#: The models that ship with the package (``ppo_<scene>.zip`` and their files beside them).
PRETRAINED = Path(__file__).resolve().parent / "pretrained"
#: How a command line names a shipped model: ``pretrained:<scene>``.
PRETRAINED_PREFIX = "pretrained:"


def pretrained_names() -> list[str]:
    """The names of the shipped models (their scenes), for ``pretrained:<name>``."""
    return sorted(p.stem.removeprefix("ppo_") for p in PRETRAINED.glob("ppo_*.zip"))


def model_path(text: str) -> Path:
    """A ``--models`` value as a path: ``pretrained:<name>`` is the shipped model of that
    name, wherever the package is installed; anything else is a path as given.
    ``ValueError`` naming the bad name and the shipped ones."""
    if not text.startswith(PRETRAINED_PREFIX):
        return Path(text)
    name = text.removeprefix(PRETRAINED_PREFIX)
    names = pretrained_names()
    if name not in names:
        raise ValueError(f"no pretrained model {name!r}; shipped: "
                         f"{', '.join(PRETRAINED_PREFIX + n for n in names)}")
    return PRETRAINED / f"ppo_{name}.zip"
