"""Run folders and model files: where a run's paths point, and loading a trained model.

A run folder (``config.yml``, ``model.zip``, ``vecnormalize.pkl``) is what
``fricenv train`` writes; a model file (``<algo>_*.zip`` with an optional
``<stem>_vecnormalize.pkl`` and ``<stem>.yml`` beside it) is what ships in ``pretrained/``.

A run's config records the names of the channels its model observes (``observation``,
``fricenv.envs.observation.channel_names``), and a model is used on an environment only
when the names agree (:func:`check_observation`): two layouts of nine channels have the
same shape, so the shape alone cannot tell them apart.
"""

from __future__ import annotations

import pickle
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from .layout import algo_class, check_algo
from .rollouts import TrainedController

#: The checkout holding ``agents/``: paths a run records are relative to it when inside it.
REPO_ROOT = Path(__file__).resolve().parents[1]
def portable_path(path: Path) -> str:
    """``path`` as a run config records it: relative to the repository (or else to the
    working folder) when it lies inside, so a config committed or copied to another
    machine names no folder of the one that trained it."""
    p = Path(path).resolve()
    for base in (REPO_ROOT, Path.cwd().resolve()):
        if p.is_relative_to(base):
            return p.relative_to(base).as_posix()
    return str(path)


def find_vecnormalize(model_path: Path) -> Path | None:
    """``<stem>_vecnormalize.pkl`` next to the model, else ``vecnormalize.pkl`` (run folder)."""
    for cand in (model_path.with_name(model_path.stem + "_vecnormalize.pkl"),
                 model_path.with_name("vecnormalize.pkl")):
        if cand.exists():
            return cand
    return None


def _read_config(cfg_file: Path) -> dict:
    """A run's config as a dict; ``ValueError`` naming the file when it is damaged (YAML's
    or the decoder's own error named no file)."""
    try:
        config = yaml.safe_load(cfg_file.read_text()) or {}
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        raise ValueError(f"{cfg_file}: cannot read the run config ({type(e).__name__}: "
                         f"{e})") from None
    if not isinstance(config, dict):
        raise ValueError(f"{cfg_file}: a run config must be a mapping, got a "
                         f"{type(config).__name__}")
    return config


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
        config = _read_config(cfg_file)
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
    # SB3, zipfile, torch and pickle each raise their own error for a damaged file (a
    # BadZipFile, an EOFError, an UnpicklingError), and none names the file
    try:
        model = algo_class(algo).load(model_path, device="cpu")
    except Exception as e:
        raise ValueError(f"{model_path}: cannot load the {algo} model ({type(e).__name__}: "
                         f"{e})") from e
    vn = None
    vn_path = find_vecnormalize(model_path)
    if vn_path is not None:
        try:
            with open(vn_path, "rb") as fh:
                vn = pickle.load(fh)
            vn.training = False
        except Exception as e:
            raise ValueError(f"{vn_path}: cannot load the observation normalisation "
                             f"({type(e).__name__}: {e})") from e
    return TrainedController(model, vn, name=algo), config


def observation_names(scene: Any, env_kwargs: Mapping[str, Any] | None = None) -> list[str]:
    """The names of the channels an environment of ``scene`` made with ``env_kwargs``
    observes, in order (what a run's config records as ``observation``)."""
    from fricenv.envs.observation import channel_names
    from fricenv.envs.setup import EnvSetup

    kw = dict(env_kwargs or {})
    kw.pop("max_episode_steps", None)
    return channel_names(EnvSetup.build(scene, **kw))


def check_observation(config: Mapping[str, Any], names: list[str], where: Any) -> None:
    """``ValueError`` naming ``where`` (a run or model file) and the first channel that
    differs unless the channels ``config`` records (``observation``) are ``names``, those
    of the environment the model is to run on. A config without the record (a bare model
    file) passes: its shape is all there is to check."""
    recorded = config.get("observation")
    if recorded is None:
        return
    recorded = list(recorded)
    if recorded == names:
        return
    diff = next((i for i, (a, b) in enumerate(zip(recorded, names, strict=False)) if a != b),
                min(len(recorded), len(names)))
    have = recorded[diff] if diff < len(recorded) else "(none)"
    want = names[diff] if diff < len(names) else "(none)"
    raise ValueError(f"{where}: the model observes channels {recorded}, the environment "
                     f"gives {names}: channel {diff} is {have!r} for the model, {want!r} "
                     "for the environment")
