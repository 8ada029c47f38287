"""Hyperparameters in rl-baselines3-zoo's yml format: reading, overrides, type checks.

YAML 1.1 reads ``1e-3`` (no dot) as a string, and a string or an out-of-range number used
to fail deep inside SB3, after the run folder was written; so every known hyperparameter
is coerced and checked here, once, for the file and for the command line's overrides.
``split_hyperparams`` then turns a checked entry into what ``train`` builds from.
"""

from __future__ import annotations

import ast
import inspect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from .layout import MAX_PLANTS, SCENE_ENV_IDS, algo_class, check_algo, check_scene

HYPERPARAMS_DIR = Path(__file__).resolve().parent / "hyperparams"


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


#: What a known hyperparameter may be: ``check(key, value)`` returns the value, coerced, or
#: raises a ``ValueError`` naming ``key`` and ``value``.
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
    #: DAgger from the MPC before training (``fricenv_agents.imitation``); None: none.
    warm_start: dict[str, Any] | None = None


def split_hyperparams(algo: str, hp: dict[str, Any]) -> RunSpec:
    """Validate an entry and turn it into what ``train`` needs (``ValueError`` if bad)."""
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
    warm_start = hp.pop("warm_start", None)
    if warm_start is not None:
        if algo != "ppo":
            raise ValueError(f"warm_start needs an on-policy actor-critic (ppo), not {algo!r}")
        from .imitation import WarmStart

        warm_start = WarmStart.from_mapping(warm_start).as_dict()
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
    return RunSpec(n_timesteps, n_envs, norm, env_kwargs, policy, hp, warm_start)
