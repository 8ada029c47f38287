"""Shared pieces of training and evaluation: names, seeds, hyperparameters, rollouts.

Training and evaluation must agree on how an environment is built, how seeds are laid out
(evaluation episodes must never be ones the agent trained on) and how an episode is scored,
so all of that lives here once.
"""

from __future__ import annotations

import argparse
import ast
import math
import pickle
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import yaml

import fricenv  # noqa: F401  (registers the environments)
from fricenv.envs import ENV_IDS
from fricenv.envs.scenes import SCENES, Scene

if TYPE_CHECKING:
    from stable_baselines3.common.base_class import BaseAlgorithm

#: Scene name -> registered Gymnasium id (the key of the hyperparameter files).
SCENE_ENV_IDS: dict[str, str] = {scene: env_id for env_id, scene in ENV_IDS.items()}
ALGOS = ("ppo", "sac")
HYPERPARAMS_DIR = Path(__file__).resolve().parent / "hyperparams"
#: The checkout holding ``agents/``: paths a run records are relative to it when inside it.
REPO_ROOT = HYPERPARAMS_DIR.parents[1]


def portable_path(path: Path) -> str:
    """``path`` as a run config records it: relative to the repository (or else to the
    working folder) when it lies inside, so a config committed or copied to another
    machine names no folder of the one that trained it."""
    p = Path(path).resolve()
    for base in (REPO_ROOT, Path.cwd().resolve()):
        if p.is_relative_to(base):
            return p.relative_to(base).as_posix()
    return str(path)

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
    if isinstance(seed, bool) or int(seed) != seed or not 0 <= seed < MAX_TRAIN_SEED:
        raise ValueError(f"seed must be an integer in [0, {MAX_TRAIN_SEED}), got {seed!r}")
    return int(seed)


# -- names ----------------------------------------------------------------------------------
def check_scene(scene: str) -> str:
    if scene not in SCENES:
        raise ValueError(f"unknown scene {scene!r}; expected one of {sorted(SCENES)}")
    return scene


def check_algo(algo: str) -> str:
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {algo!r}; expected one of {list(ALGOS)}")
    return algo


def algo_class(algo: str) -> type[BaseAlgorithm]:
    from stable_baselines3 import PPO, SAC

    classes: dict[str, type[BaseAlgorithm]] = {"ppo": PPO, "sac": SAC}
    return classes[check_algo(algo)]


# -- hyperparameters (rl-baselines3-zoo style) ----------------------------------------------
def load_hyperparams(algo: str, scene: str, path: str | Path | None = None) -> dict[str, Any]:
    """The entry of ``scene``'s environment id in ``<algo>.yml`` (or the file ``path``).

    A file that cannot be read or parsed, or holds no mapping there, is a ``ValueError``
    naming it (the command lines turn that into a usage error, not a traceback).
    """
    check_algo(algo)
    check_scene(scene)
    path = Path(path) if path is not None else HYPERPARAMS_DIR / f"{algo}.yml"
    try:
        with open(path) as fh:
            table = yaml.safe_load(fh)
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"cannot read hyperparameter file {path}: "
                         f"{getattr(e, 'strerror', None) or e}") from None
    except yaml.YAMLError as e:
        raise ValueError(f"hyperparameter file {path} is not valid YAML: "
                         f"{' '.join(str(e).split())}") from None
    table = {} if table is None else table
    if not isinstance(table, dict):
        raise ValueError(f"hyperparameter file {path} must map environment ids to entries, "
                         f"got {type(table).__name__} {table!r:.60}")
    env_id = SCENE_ENV_IDS[scene]
    if env_id not in table:
        raise ValueError(f"{path} has no entry for {env_id!r} (scene {scene!r}); "
                         f"entries: {sorted(map(str, table))}")
    entry = table[env_id]
    if not isinstance(entry, dict):
        raise ValueError(f"{path}: the entry {env_id!r} must be a mapping of "
                         f"hyperparameters, got {entry!r:.60}")
    return dict(entry)


def parse_value(text: str) -> Any:
    """``KEY:VALUE`` override value: a YAML scalar, list or mapping (``0.99``, ``[64, 64]``)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise ValueError(f"cannot parse {text!r}: {' '.join(str(e).split())}") from None


def apply_overrides(hp: dict[str, Any], overrides: Sequence[str]) -> dict[str, Any]:
    """Zoo-style ``-params key:value ...`` overrides."""
    hp = dict(hp)
    for item in overrides:
        key, sep, value = item.partition(":")
        if not sep or not key.strip():
            raise ValueError(f"hyperparameter override must be KEY:VALUE, got {item!r}")
        try:
            hp[key.strip()] = parse_value(value)
        except ValueError as e:
            raise ValueError(f"hyperparameter override {item!r}: {e}") from None
    return hp


# What each known hyperparameter may be. YAML 1.1 reads ``1e-3`` (no dot) as a string, and a
# string or an out-of-range number only failed deep inside SB3, after the run folder was
# written; so numbers are coerced and checked here, once, for the file and the overrides.
Check = Callable[[str, Any], Any]


def _bad(key: str, value: Any, want: str) -> ValueError:
    return ValueError(f"hyperparameter {key} must be {want}, got {value!r}")


def _real(lo: float = -math.inf, hi: float = math.inf, *, open_lo: bool = False,
          open_hi: bool = False, whole: bool = False, optional: bool = False) -> Check:
    """A finite number in a range (numeric strings too); ``whole``: returned as an int."""
    if math.isinf(lo) and math.isinf(hi):
        rng = "a finite number"
    elif math.isinf(hi):
        rng = f"a finite number {'>' if open_lo else '>='} {lo:g}"
    else:
        rng = f"a number in {'(' if open_lo else '['}{lo:g}, {hi:g}{')' if open_hi else ']'}"
    want = ("a whole " + rng.removeprefix("a ") if whole else rng) + (
        " or null" if optional else "")

    def check(key: str, value: Any) -> Any:
        if value is None and optional:
            return None
        x = value
        if isinstance(x, str):
            try:
                x = float(x)
            except ValueError:
                raise _bad(key, value, want) from None
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise _bad(key, value, want)
        if (x < lo or x > hi or (open_lo and x == lo) or (open_hi and x == hi)
                or (whole and x != int(x))):
            raise _bad(key, value, want)
        return int(x) if whole else float(x)

    return check


def _int(lo: int, hi: int | None = None, also: tuple[int, ...] = ()) -> Check:
    """An integer (not a float or bool, which would be truncated or read as 0/1)."""
    want = f"an integer >= {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
    want += "".join(f" or {a}" for a in also)

    def check(key: str, value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not (
                value in also or (lo <= value and (hi is None or value <= hi))):
            raise _bad(key, value, want)
        return value

    return check


def _flag(key: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise _bad(key, value, "true or false")
    return value


def _number_or(number: Check, prefix: str | None = None, word: str | None = None,
               prefixed: Check | None = None) -> Check:
    """A number, or ``<prefix><number>`` (``lin_3e-4``: a linear decay to 0, as in the zoo;
    ``auto_0.1``: SAC's learned entropy coefficient starting at 0.1; that number checked by
    ``prefixed`` if given), or the string ``word`` (``auto``)."""
    def check(key: str, value: Any) -> Any:
        if word is not None and value == word:
            return value
        if prefix is not None and isinstance(value, str) and value.startswith(prefix):
            try:
                (prefixed or number)(key, value[len(prefix):])
            except ValueError as e:
                raise ValueError(f"{e} (in {value!r})") from None
            return value
        return number(key, value)

    return check


def _train_freq(key: str, value: Any) -> Any:
    if isinstance(value, (list, tuple)) and len(value) == 2 and value[1] in ("step", "episode"):
        return [_int(1)(key, value[0]), value[1]]
    try:
        return _int(1)(key, value)
    except ValueError:
        raise _bad(key, value, "an integer >= 1 or [n, step|episode]") from None


_COUNT = _int(1)
_COMMON_KINDS: dict[str, Check] = {
    "n_timesteps": _real(1, whole=True),
    "n_envs": _int(1, MAX_PLANTS),
    "learning_rate": _number_or(_real(0, open_lo=True), "lin_"),
    "gamma": _real(0, 1, open_lo=True),
    "use_sde": _flag,
    "sde_sample_freq": _int(-1),
    "stats_window_size": _COUNT,
    "batch_size": _COUNT,
}
#: Known hyperparameters per algorithm -> what they may be (others are passed on unchecked).
HYPERPARAM_KINDS: dict[str, dict[str, Check]] = {
    "ppo": {
        **_COMMON_KINDS,
        "n_steps": _COUNT,
        "n_epochs": _COUNT,
        "gae_lambda": _real(0, 1),
        "clip_range": _number_or(_real(0, open_lo=True), "lin_"),
        "clip_range_vf": _number_or(_real(0, open_lo=True, optional=True), "lin_"),
        "normalize_advantage": _flag,
        "ent_coef": _real(0),
        "vf_coef": _real(0),
        "max_grad_norm": _real(0, open_lo=True),
        "target_kl": _real(0, open_lo=True, optional=True),
    },
    "sac": {
        **_COMMON_KINDS,
        "buffer_size": _COUNT,
        "learning_starts": _int(0),
        "tau": _real(0, 1, open_lo=True),
        "train_freq": _train_freq,
        "gradient_steps": _int(1, also=(-1,)),
        "ent_coef": _number_or(_real(0), "auto_", "auto", prefixed=_real(0, open_lo=True)),
        "target_update_interval": _COUNT,
        "target_entropy": _number_or(_real(), word="auto"),
        "use_sde_at_warmup": _flag,
        "optimize_memory_usage": _flag,
    },
}


def check_hyperparams(algo: str, hp: dict[str, Any]) -> dict[str, Any]:
    """``hp`` with the known keys' values checked and numeric strings made numbers;
    ``ValueError`` naming the first bad key and value."""
    kinds = HYPERPARAM_KINDS[check_algo(algo)]
    return {k: kinds[k](k, v) if k in kinds else v for k, v in hp.items()}


def _schedule(value: Any) -> Any:
    """``lin_3e-4`` -> a linear decay to 0 (as in the zoo); numbers pass through."""
    if isinstance(value, str) and value.startswith("lin_"):
        start = float(value[4:])

        def linear(progress_remaining: float) -> float:
            return progress_remaining * start

        return linear
    return value


_ACTIVATIONS = {"tanh": "Tanh", "relu": "ReLU", "elu": "ELU", "leaky_relu": "LeakyReLU"}


def _policy_kwargs(value: Any) -> dict[str, Any]:
    """A mapping, or the zoo's string form ``"dict(net_arch=[64, 64])"`` (literals only)."""
    import torch.nn as nn

    if isinstance(value, str):
        bad = ValueError(f"policy_kwargs string must be dict(key=literal, ...), got {value!r}")
        try:
            tree = ast.parse(value, mode="eval").body
        except SyntaxError:
            raise bad from None
        if not (isinstance(tree, ast.Call) and getattr(tree.func, "id", None) == "dict"
                and not tree.args and all(k.arg for k in tree.keywords)):
            raise bad
        kw = {}
        for k in tree.keywords:
            if isinstance(k.value, ast.Attribute) and getattr(k.value.value, "id", "") == "nn":
                kw[k.arg] = k.value.attr.lower().replace("leakyrelu", "leaky_relu")
            else:
                try:
                    kw[k.arg] = ast.literal_eval(k.value)
                except ValueError:
                    raise bad from None
        value = kw
    if not isinstance(value, dict):
        raise ValueError(f"policy_kwargs must be a mapping, got {value!r}")
    out = dict(value)
    act = out.get("activation_fn")
    if isinstance(act, str):
        name = _ACTIVATIONS.get(act.lower())
        if name is None:
            raise ValueError(f"activation_fn must be one of {sorted(_ACTIVATIONS)}, got {act!r}")
        out["activation_fn"] = getattr(nn, name)
    return out


@dataclass(frozen=True)
class RunSpec:
    """A hyperparameter entry split into run settings and constructor arguments."""

    n_timesteps: int
    n_envs: int
    normalize: dict[str, Any] | None
    env_kwargs: dict[str, Any]
    policy: str
    algo_kwargs: dict[str, Any]


def split_hyperparams(algo: str, hp: dict[str, Any]) -> RunSpec:
    """Validate an entry and turn it into what ``train`` needs (``ValueError`` if bad)."""
    import inspect

    hp = check_hyperparams(algo, hp)
    n_timesteps = hp.pop("n_timesteps", 100_000)
    n_envs = hp.pop("n_envs", 1)
    norm = hp.pop("normalize", False)
    if isinstance(norm, str):
        try:
            norm = ast.literal_eval(norm)
        except (ValueError, SyntaxError):
            raise ValueError(f"normalize must be a bool or a mapping, got {norm!r}") from None
    if norm is True:
        norm = {}
    elif norm is False or norm is None:
        norm = None
    elif not isinstance(norm, dict):
        raise ValueError(f"normalize must be a bool or a mapping, got {norm!r}")
    env_kwargs = hp.pop("env_kwargs", None) or {}
    if not isinstance(env_kwargs, dict):
        raise ValueError(f"env_kwargs must be a mapping, got {env_kwargs!r}")
    env_kwargs = dict(env_kwargs)
    policy = str(hp.pop("policy", "MlpPolicy"))
    for key in ("learning_rate", "clip_range", "clip_range_vf"):
        if key in hp:
            hp[key] = _schedule(hp[key])
    if "policy_kwargs" in hp:
        hp["policy_kwargs"] = _policy_kwargs(hp["policy_kwargs"])
    if "train_freq" in hp and isinstance(hp["train_freq"], list):
        hp["train_freq"] = tuple(hp["train_freq"])
    allowed = set(inspect.signature(algo_class(algo)).parameters) - {
        "self", "policy", "env", "seed", "device", "verbose", "tensorboard_log"}
    unknown = sorted(set(hp) - allowed)
    if unknown:
        raise ValueError(f"unknown {algo} hyperparameter(s) {unknown}")
    return RunSpec(n_timesteps, n_envs, norm, env_kwargs, policy, hp)


# -- environments ---------------------------------------------------------------------------
def make_sb3_env(scene: str, n_envs: int, seed: int, env_kwargs: dict | None = None,
                 monitor_file: str | Path | None = None) -> Any:
    """The native SB3 vector env (one numba call per step), monitored, seeded ``seed + i``."""
    from stable_baselines3.common.vec_env import VecMonitor

    from fricenv.envs.sb3 import StickSlipSB3VecEnv

    venv = StickSlipSB3VecEnv(num_envs=n_envs, scene=scene, **(env_kwargs or {}))
    venv.seed(seed)
    return VecMonitor(venv, filename=None if monitor_file is None else str(monitor_file),
                      info_keywords=("episode_stick_fraction",))


# -- controllers ----------------------------------------------------------------------------
class Controller(Protocol):
    """What a trained model and every baseline offer: SB3's ``predict``."""

    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]: ...


class TrainedController:
    """A trained SB3 model plus its observation normalisation, as one ``predict``.

    The model was trained on normalised observations; evaluating it on raw ones would be
    silently wrong, so the statistics travel with it. They are used read-only.
    """

    def __init__(self, model: Any, vecnormalize: Any | None = None, name: str = "agent"):
        self.model = model
        self.vecnormalize = vecnormalize
        self.name = name
        self.action_space = model.action_space

    def predict(self, observation: np.ndarray, state: Any = None,
                episode_start: np.ndarray | None = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        obs = np.asarray(observation, dtype=np.float32)
        if self.vecnormalize is not None and self.vecnormalize.norm_obs:
            obs = self.vecnormalize.normalize_obs(obs).astype(np.float32)
        action, state = self.model.predict(obs, state, episode_start, deterministic)
        return np.asarray(action, dtype=np.float32), state


def find_vecnormalize(model_path: Path) -> Path | None:
    """``<stem>_vecnormalize.pkl`` next to the model, else ``vecnormalize.pkl`` (run folder)."""
    for cand in (model_path.with_name(model_path.stem + "_vecnormalize.pkl"),
                 model_path.with_name("vecnormalize.pkl")):
        if cand.exists():
            return cand
    return None


def locate_model(path: str | Path, algo: str | None = None) -> tuple[Path, dict, str]:
    """(model file, run config, algorithm) of a run folder (``config.yml`` + ``model.zip``)
    or a model file, without loading it; ``ValueError`` saying what is missing.

    A model file's config is ``<stem>.yml`` beside it, or the ``config.yml`` of the run
    folder it lies in (``<run>/model.zip``). The algorithm comes from the config, else
    ``algo``, else the file name's prefix (``ppo_...zip``).
    """
    path = Path(path)
    config: dict = {}
    if path.is_dir():
        cfg_file = path / "config.yml"
        if not cfg_file.exists():
            raise ValueError(f"{path} is not a run folder (no config.yml)")
        model_path = path / "model.zip"
    else:
        model_path = path
        cfg_file = path.with_suffix(".yml")
        if not cfg_file.exists():
            cfg_file = path.parent / "config.yml"
    if cfg_file.exists():
        config = yaml.safe_load(cfg_file.read_text()) or {}
    if not model_path.exists():
        raise ValueError(f"no model at {model_path}" + (
            " (an unfinished training run?)" if path.is_dir() else ""))
    algo = config.get("algo") or algo or model_path.stem.split("_")[0]
    try:
        check_algo(algo)
    except ValueError as e:
        raise ValueError(f"{path}: {e} (name the file <algo>_*.zip or put a config beside "
                         "it)") from None
    return model_path, config, algo


def load_controller(path: str | Path, algo: str | None = None) -> tuple[TrainedController, dict]:
    """Load a run folder or a model file (see ``locate_model``); returns the controller
    and the run config (empty for a bare file)."""
    model_path, config, algo = locate_model(path, algo)
    model = algo_class(algo).load(model_path, device="cpu")
    vn = None
    vn_path = find_vecnormalize(model_path)
    if vn_path is not None:
        with open(vn_path, "rb") as fh:
            vn = pickle.load(fh)
        vn.training = False
    return TrainedController(model, vn, name=algo), config


# -- rollouts -------------------------------------------------------------------------------
@dataclass
class EpisodeMetrics:
    """Per-episode scores (arrays over episodes)."""

    stick_fraction: np.ndarray
    rms_vr: np.ndarray  #: RMS of v - V over the episode
    rms_vr_fluct: np.ndarray  #: RMS of v - V about its episode mean (vibration)
    effort: np.ndarray
    ret: np.ndarray
    length: np.ndarray

    FIELDS = ("stick_fraction", "rms_vr", "rms_vr_fluct", "effort", "ret", "length")

    @classmethod
    def concat(cls, parts: Iterable[EpisodeMetrics]) -> EpisodeMetrics:
        parts = list(parts)
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in cls.FIELDS))

    def as_dict(self) -> dict[str, list[float]]:
        return {f: getattr(self, f).tolist() for f in self.FIELDS}


def rollout(controller: Controller, scene: str | Scene, seed: int | Sequence[int],
            n_episodes: int,
            env_kwargs: dict | None = None) -> EpisodeMetrics:
    """Run ``n_episodes`` episodes side by side to the horizon.

    Plant j is seeded ``seed + j`` (or ``seed[j]`` for a list), so two controllers run with
    the same seed face the same episodes.

    Metrics are exact integrals over the episode: the kernel reports, per control interval,
    the stuck time and the mean and variance of ``v - V`` (``info``), so ``int (v - V)^2``
    follows without sampling.
    """
    from gymnasium.vector import AutoresetMode

    from fricenv.envs.vector import StickSlipVectorEnv

    # An episode that ends early (its state left the observation box) is restarted by the
    # next step (next-step autoreset) and masked out of the metrics from then on (``alive``),
    # while the others run on to the horizon.
    venv = StickSlipVectorEnv(num_envs=n_episodes, scene=scene,
                              autoreset_mode=AutoresetMode.NEXT_STEP, **(env_kwargs or {}))
    # a model-based controller (agents.mpc) reads the plants' exact states while it runs
    bind = getattr(controller, "bind", None)
    try:
        obs, _ = venv.reset(seed=seed if isinstance(seed, int) else [int(s) for s in seed])
        if callable(bind):
            bind(venv)
        alive = np.ones(n_episodes, dtype=bool)
        n = np.zeros(n_episodes)
        ret = np.zeros(n_episodes)
        stick = np.zeros(n_episodes)
        effort = np.zeros(n_episodes)
        vr1 = np.zeros(n_episodes)  # sum over intervals of mean(v - V)
        vr2 = np.zeros(n_episodes)  # sum over intervals of mean((v - V)^2)
        start = np.ones(n_episodes, dtype=bool)
        state = None
        for _ in range(venv.max_episode_steps):
            action, state = controller.predict(obs, state, start, deterministic=True)
            start[:] = False
            obs, r, term, trunc, info = venv.step(np.asarray(action, dtype=np.float32))
            mean_vr = info["mean_relative_velocity"]
            w = alive.astype(float)
            n += w
            ret += w * r
            stick += w * info["stick_fraction"]
            effort += w * info["effort"]
            vr1 += w * mean_vr
            vr2 += w * (info["velocity_variance"] + mean_vr**2)
            alive &= ~(term | trunc)
            if not alive.any():
                break
    finally:
        if callable(bind):
            bind(None)
        venv.close()
    m1 = vr1 / n
    m2 = vr2 / n
    return EpisodeMetrics(stick / n, np.sqrt(m2), np.sqrt(np.maximum(m2 - m1**2, 0.0)),
                          effort / n, ret, n)


def summarize(values: np.ndarray) -> tuple[float, float]:
    """Mean and sample standard deviation (0 for a single value)."""
    values = np.asarray(values, dtype=float)
    std = float(values.std(ddof=1)) if values.size > 1 else 0.0
    return float(values.mean()), std


def fmt_pm(mean: float, std: float, digits: int = 3) -> str:
    if not math.isfinite(mean):
        return "n/a"
    return f"{mean:.{digits}f} ± {std:.{digits}f}"


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """argparse's defaults in the help, except where there is nothing to show: a default
    of None (a required option, or one whose help names its own default)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        if action.default is None or action.required or "(default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)
