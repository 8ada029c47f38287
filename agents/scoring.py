"""Scoring controllers on the held-out episodes of ``fricenv_agents.evaluate``: the rows
of a table (trained models grouped by algorithm, the baselines), their episodes, the
markdown table and the plots.

The command line (parser, argument checks) lives in :mod:`.evaluate`, which imports this
module (and with it numba, the kernels and stable-baselines3) only after parsing, so that
``--help`` stays light.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fricenv.envs.observation import CHANNELS
from fricenv.envs.scenes import Scene

from .baselines import (
    ActionMap,
    Baseline,
    ZeroExcitation,
    make_baseline,
    search_best_constant,
)
from .layout import BASELINES, SCENE_ENV_IDS, eval_env_seed, eval_seeds
from .rollouts import (
    Controller,
    EpisodeMetrics,
    TrainedController,
    fmt_pm,
    rollout,
    summarize,
)
from .runs import check_observation, load_controller, observation_names
from .statistics import Interval, iqm_ci

LABELS = {"ppo": "PPO", "sac": "SAC"}
#: The observed setting's channels (the time history plots them).
_U0, _NU = CHANNELS.index("u0"), CHANNELS.index("nu")
COLUMNS = (
    ("stick_fraction", "stick-time fraction", 4),
    ("rms_vr", "RMS relative velocity", 3),
    ("rms_vr_fluct", "RMS fluctuation", 3),
    ("effort", "actuation effort", 4),
    ("ret", "return", 2),
)


@dataclass
class Entry:
    """One row of the table: a controller (or a group of trained models) and its scores."""

    key: str
    label: str
    kind: str  # "baseline" or "trained"
    factories: list[Callable[[int], Controller]]  # controller for evaluation seed k
    info: dict[str, Any] = field(default_factory=dict)
    metrics: EpisodeMetrics | None = None
    seed_means: dict[str, list[float]] = field(default_factory=dict)
    n_seeds: int = 0  #: evaluation seeds ``run_entry`` ran (0 before)
    episodes: int = 0  #: episodes per evaluation seed
    intervals: dict[str, Interval] = field(default_factory=dict)  #: IQM and its 95 % CI

    @property
    def scores(self) -> EpisodeMetrics:
        """The metrics ``run_entry`` measured (tables and plots read them only after)."""
        if self.metrics is None:
            raise RuntimeError(f"{self.key!r} has not been evaluated yet")
        return self.metrics

    def matrix(self, name: str) -> np.ndarray:
        """Metric ``name`` as a ``(models, evaluation seeds x episodes)`` matrix: one row
        per trained model (one for a baseline), columns in ``run_entry``'s order (seed by
        seed, episode by episode), the cell :mod:`.statistics` resamples."""
        values = np.asarray(getattr(self.scores, name))
        shape = (len(self.factories), self.n_seeds * self.episodes)
        if values.size != shape[0] * shape[1]:
            raise ValueError(f"{self.key!r}: {values.size} episodes of {name!r}, expected "
                             f"{shape[0]} models x {self.n_seeds} seeds x {self.episodes}")
        return values.reshape(shape)

    def interval(self, name: str) -> Interval:
        """The IQM of metric ``name`` over all models and episodes, with its 95 %
        bootstrap interval (training runs, then episodes within each evaluation seed's
        block of plant seeds; computed once)."""
        if name not in self.intervals:
            self.intervals[name] = iqm_ci(self.matrix(name), strata=self.n_seeds)
        return self.intervals[name]


def _constant(controller: Controller) -> Callable[[int], Controller]:
    """A factory giving the same controller for every evaluation seed."""
    return lambda k: controller


# -- building the controllers -----------------------------------------------------------------
def load_models(paths: list[Path]) -> dict[Path, tuple[TrainedController, dict]]:
    """Each run folder's or model file's controller and config; ``ValueError`` naming a file
    SB3 cannot load (a corrupt zip was a traceback after the output folder was made)."""
    loaded = {}
    for p in paths:
        try:
            loaded[p] = load_controller(p)
        except Exception as e:
            raise ValueError(f"{p}: cannot load the model ({type(e).__name__}: {e})") from e
    return loaded


#: Settings of a run's ``env_kwargs`` that shape its training episodes only: the runs are
#: scored on the scene's own episodes (``fricenv evaluate --max-steps`` sets another length).
TRAINING_ONLY = ("max_episode_steps",)


def trained_entries(paths: list[Path], scene: str,
                    loaded: dict[Path, tuple[TrainedController, dict]] | None = None,
                    ) -> tuple[list[Entry], dict]:
    """Group run folders of ``scene`` by algorithm (model files stay on their own rows);
    also return the runs' common env kwargs, less the ``TRAINING_ONLY`` ones. ``ValueError``
    for a model that does not fit the scene. ``loaded``: what ``load_models`` returned, to
    load nothing twice."""
    from .baselines import ActionMap

    loaded = loaded if loaded is not None else load_models(paths)
    groups: dict[str, list[tuple[Any, dict, Path]]] = {}
    env_kwargs: dict | None = None
    for p in paths:
        ctrl, cfg = loaded[p]
        if cfg.get("scene", scene) != scene:
            continue
        kw = {k: v for k, v in (cfg.get("env_kwargs") or {}).items()
              if k not in TRAINING_ONLY}
        if env_kwargs is None:
            env_kwargs = kw
        elif kw != env_kwargs:
            raise ValueError(f"{p}: env_kwargs {kw} differ from other runs' {env_kwargs}")
        try:
            want = ActionMap(scene, kw).action_space.shape
        except (TypeError, ValueError) as e:
            raise ValueError(f"{p}: its env_kwargs {kw} do not build scene {scene!r}: "
                             f"{e}") from None
        if ctrl.action_space.shape != want:
            raise ValueError(f"{p}: the model's actions have shape {ctrl.action_space.shape}, "
                             f"scene {scene!r} needs {want}")
        names = observation_names(scene, kw)
        check_observation(cfg, names, p)
        obs = ctrl.model.observation_space.shape
        if obs != (len(names),):
            raise ValueError(f"{p}: the model's observations have shape {obs}, "
                             f"the environments give {(len(names),)} (channels {names})")
        key = ctrl.name if p.is_dir() else f"{ctrl.name}:{p.name}"
        groups.setdefault(key, []).append((ctrl, cfg, p))
    entries = []
    for key, members in groups.items():
        algo, _, fname = key.partition(":")
        label = LABELS.get(algo, algo.upper())
        n = len(members)
        label += f" ({fname})" if fname else f" ({n} training seed{'s' if n > 1 else ''})"
        secs = [m[1]["train_seconds"] for m in members if m[1].get("train_seconds")]
        steps = [m[1]["timesteps_done"] for m in members if m[1].get("timesteps_done")]
        info = {"paths": [str(m[2]) for m in members],
                "train_seconds": secs, "timesteps": steps,
                "seeds": [m[1].get("seed") for m in members]}
        factories = [_constant(m[0]) for m in members]
        entries.append(Entry(key, label, "trained", factories, info))
    return entries, env_kwargs or {}


def baseline_entries(names: list[str], scene: str, env_kwargs: dict, out: Path,
                     search: dict[str, Any]) -> list[Entry]:
    entries = []
    for name in names:
        if name == "best_constant":
            res = search_best_constant(scene, env_kwargs, cache_dir=out, **search)
            b = res["best"]
            ctrl = make_baseline(name, scene, env_kwargs, search_kwargs={**search,
                                                                          "cache_dir": out})
            info = {"u0": b["u0"], "nu": b["nu"], "search_return": b["return_mean"],
                    "n_candidates": res["n_candidates"], "n_grid_cells": res["n_grid_cells"],
                    "search_seeds": [res["key"]["seed"],
                                     res["key"]["seed"] + res["key"]["episodes"] - 1]}
            entries.append(Entry(name, ctrl.label, "baseline", [_constant(ctrl)], info))
        elif name == "random":
            def factory(k: int, name: str = name) -> Baseline:
                return make_baseline(name, scene, env_kwargs, seed=k)

            ctrl = factory(0)
            entries.append(Entry(name, ctrl.label, "baseline", [factory], {"seed": "k"}))
        else:
            ctrl = make_baseline(name, scene, env_kwargs)
            entries.append(Entry(name, ctrl.label, "baseline", [_constant(ctrl)],
                                 ctrl.describe()))
    return entries


# -- running ----------------------------------------------------------------------------------
def run_entry(entry: Entry, scene: str | Scene, env_kwargs: dict, n_seeds: int,
              episodes: int, bar: Any = None) -> None:
    """Score ``entry`` on every evaluation seed's episodes; ``bar``: a tqdm bar advanced
    by one per batch of episodes."""
    parts = []
    per_seed: dict[str, list[float]] = {f: [] for f, _, _ in COLUMNS}
    for factory in entry.factories:
        for m in _seed_blocks(entry, factory, scene, env_kwargs, n_seeds, episodes):
            parts.append(m)
            for f, _, _ in COLUMNS:
                per_seed[f].append(float(getattr(m, f).mean()))
            if bar is not None:
                bar.update()
    entry.metrics = EpisodeMetrics.concat(parts)  # models x seeds x episodes, in order
    entry.seed_means = per_seed
    entry.n_seeds, entry.episodes = n_seeds, episodes
    entry.intervals = {}


def _seed_blocks(entry: Entry, factory: Callable[[int], Controller], scene: str | Scene,
                 env_kwargs: dict, n_seeds: int, episodes: int) -> list[EpisodeMetrics]:
    """One controller's metrics on each evaluation seed's episodes. A trained model is the
    same deterministic policy for every seed and each plant runs on its own, so all its
    episodes run side by side in one vector env (plant seeds as seed by seed, the same
    episodes), which spares the policy's per-call overhead; other controllers (the MPC's
    and the random baseline's draws depend on the seed and on the batch) run seed by
    seed."""
    if entry.kind != "trained":
        return [rollout(factory(k), scene, eval_env_seed(k), episodes, env_kwargs)
                for k in range(n_seeds)]
    seeds = [eval_env_seed(k) + j for k in range(n_seeds) for j in range(episodes)]
    m = rollout(factory(0), scene, seeds, len(seeds), env_kwargs)
    return [EpisodeMetrics(*(getattr(m, f)[k * episodes:(k + 1) * episodes]
                             for f in EpisodeMetrics.FIELDS)) for k in range(n_seeds)]


def _summary(entry: Entry) -> dict[str, Any]:
    m = entry.scores
    out: dict[str, Any] = {"label": entry.label, "kind": entry.kind, "n": int(m.ret.size)}
    for f, _, _ in COLUMNS:
        mean, std = summarize(getattr(m, f))
        out[f] = {"mean": mean, "std": std,
                  "std_of_seed_means": summarize(np.array(entry.seed_means[f]))[1]}
    return out


# -- writing ----------------------------------------------------------------------------------
def _span(values: Sequence[float], spec: str) -> str:
    """``lo–hi`` of ``values`` formatted with ``spec``; one value when they all agree."""
    lo, hi = format(min(values), spec), format(max(values), spec)
    return lo if lo == hi else f"{lo}–{hi}"


def markdown(scene: str, entries: list[Entry], n_seeds: int, episodes: int,
             plots: list[str], env_kwargs: dict | None = None) -> str:
    sc = ActionMap(scene, env_kwargs).scene  # the scene as evaluated, not the preset
    zero = next((e for e in entries if e.key == "zero"), None)
    best = next((e for e in entries if e.key == "best_constant"), None)
    z_stick = float(zero.scores.stick_fraction.mean()) if zero else float("nan")
    ref = zero.label.split(" (")[0] if zero else "zero excitation"
    head = ["controller", "n"] + [name for _, name, _ in COLUMNS] + [f"stick cut vs {ref}"]
    lines = [
        f"# Stick-slip suppression: scene `{scene}` ({SCENE_ENV_IDS[scene]})",
        "",
        f"{sc.description}",
        "",
        *([f"Environment settings changed from the scene's: `{env_kwargs}` (the values "
           "below are those used).", ""] if env_kwargs else []),
        f"Mean ± std over n episodes of {sc.max_episode_steps} control steps "
        f"(dt = {sc.control_dt:.4f}): {n_seeds} evaluation seeds x {episodes} episodes, "
        "times the number of trained models for an agent. All controllers face the same "
        "episodes; none was trained or tuned on them.",
        "",
        "| " + " | ".join(head) + " |",
        "|" + "|".join(["---"] + ["---:"] * (len(head) - 1)) + "|",
    ]
    for e in entries:
        m = e.scores
        cells = [e.label, str(m.ret.size)]
        for f, _, d in COLUMNS:
            cells.append(fmt_pm(*summarize(getattr(m, f)), digits=d))
        cut = 1.0 - float(m.stick_fraction.mean()) / z_stick if zero and z_stick > 0 else None
        cells.append("—" if cut is None or e.key == "zero" else f"{100 * cut:.1f} %")
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        "Columns: stick-time fraction = time stuck / episode time (exact, event-driven "
        "plant); RMS relative velocity = sqrt of the time mean of (v − V)², which is V = "
        f"{sc.params.V:g} for steady sliding with the block at rest; RMS fluctuation = the "
        "same about the episode's mean of v − V (how much the block vibrates); actuation "
        "effort = mean excitation power relative to the strongest allowed (0 to 1); return "
        f"= the scene's reward summed over the episode (weights stick, velocity, effort = "
        f"{', '.join(f'{w:g}' for w in sc.reward_weights)}).",
        "",
    ]
    if best is not None:
        lines.append(f"Best constant excitation: u0 = {best.info['u0']:.3f}, "
                     f"nu = {best.info['nu']:.3f}, chosen by return among "
                     f"{best.info['n_candidates']} of {best.info['n_grid_cells']} grid cells "
                     "(cells whose steady-state stick fraction, from `fricenv.sweep."
                     "regime_map`, is within 0.05 of the lowest), on search episodes "
                     f"(plant seeds {best.info['search_seeds'][0]}–"
                     f"{best.info['search_seeds'][1]}).")
        lines.append("")
    for e in entries:
        if e.kind != "trained":
            continue
        secs = e.info.get("train_seconds") or []
        steps = e.info.get("timesteps") or []
        if secs:
            done = _span(steps, "") if steps else "?"
            lines.append(f"- {e.label}: training wall time {_span(secs, '.0f')} s "
                         f"per run ({done} steps, 2-core CPU).")
        paired = []
        for b in entries:
            if b.kind != "baseline" or b.key == "zero":
                continue
            n_ep = b.scores.ret.size
            agent = e.scores.ret.reshape(-1, n_ep).mean(axis=0)  # average over its models
            d = agent - b.scores.ret
            se = d.std(ddof=1) / np.sqrt(n_ep) if n_ep > 1 else 0.0
            paired.append(f"{b.label}: {d.mean():+.2f} ± {se:.2f} "
                          f"(better in {(d > 0).sum()} of {n_ep})")
        if paired:
            lines.append(f"- {e.label}, return minus baseline's on the same episodes (mean ± "
                         "standard error; the agent averaged over its models): "
                         + "; ".join(paired) + ".")
        lines.append("")
    for p in plots:
        lines.append(f"![{p}]({p})")
        lines.append("")
    return "\n".join(lines)


# -- plots ------------------------------------------------------------------------------------
def time_history(controllers: list[tuple[str, Controller]], scene: str, env_kwargs: dict,
                 seed: int, path: Path, samples: int = 16, zoom: float = 20.0) -> None:
    """One episode under each controller: v - V (fine samples, stuck shaded), u0 and nu.

    Left: the whole episode; right: its first ``zoom`` time units, where control acts.
    """
    import gymnasium as gym
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(controllers)
    fig, axes = plt.subplots(n, 2, figsize=(11, 1.6 * n + 0.7), sharex="col", squeeze=False,
                             gridspec_kw={"width_ratios": [3, 1.2]})
    amap = ActionMap(scene, env_kwargs)
    top = max(amap.u_range[1], amap.nu_range[1])
    for row, (label, ctrl) in enumerate(controllers):
        env = gym.make(SCENE_ENV_IDS[scene], scene=scene, **env_kwargs)
        u: Any = env.unwrapped  # a StickSlipEnv: sample_interval and snapshot
        obs, _ = env.reset(seed=seed)
        ts, vs, ss, tu, us, ns = [], [], [], [], [], []
        total, stuck, done = 0.0, 0.0, False
        while not done:
            a, _ = ctrl.predict(obs, deterministic=True)
            a = np.asarray(a, dtype=np.float32)
            # the coming interval, exactly and without effect on the real step
            tb, vb, sb = u.sample_interval(a, samples)
            t_now = u.snapshot()["t"]
            obs, r, term, trunc, info = env.step(a)
            ts.append(tb)
            vs.append(vb)
            ss.append(sb)
            tu.append(t_now)
            us.append(float(obs[_U0]))
            ns.append(float(obs[_NU]))
            total += float(r)
            stuck += info["stick_fraction"]
            done = term or trunc
        env.close()
        t, v, s = np.concatenate(ts), np.concatenate(vs), np.concatenate(ss)
        tu.append(t[-1])
        us.append(us[-1])
        ns.append(ns[-1])
        lo = min(-2.5, float(v.min()) - 0.1)
        for col, ax in enumerate(axes[row]):
            ax.plot(t, v, lw=0.6, color="C0")
            ax.fill_between(t, lo, 0.3, where=s, color="C3", alpha=0.3, lw=0, step="mid")
            ax.set_ylim(lo, 0.3)
            ax2 = ax.twinx()
            ax2.step(tu, us, where="post", color="C2", lw=0.9)
            ax2.step(tu, ns, where="post", color="C4", lw=0.7, ls="--")
            ax2.set_ylim(-0.05 * top, 1.05 * top)
            if col == 1:
                ax.set_xlim(t[0], t[0] + zoom)
                ax2.set_ylabel("u0, nu")
            else:
                ax.set_ylabel("v − V")
                ax.set_title(f"{label}: stick-time fraction {stuck / (len(tu) - 1):.3f}, "
                             f"return {total:.1f}", fontsize=9, loc="left")
    axes[-1, 0].set_xlabel("time τ  (stuck: red; right axis: amplitude u0 green, "
                           "frequency ratio nu purple dashed)")
    axes[-1, 1].set_xlabel(f"first {zoom:g} time units")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def learning_curves(entries: list[Entry], baselines: list[Entry], path: Path) -> bool:
    """Periodic-evaluation return and stick fraction against training steps, per group."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = []
    for e in entries:
        runs = []
        for p in e.info.get("paths", []):
            f = Path(p) / "evaluations.npz" if Path(p).is_dir() else None
            if f is not None and f.exists():
                with np.load(f) as z:
                    runs.append((z["timesteps"], z["results"].mean(axis=1), z["stick_fraction"]))
        if runs:
            curves.append((e, runs))
    if not curves:
        return False
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6))
    for c, (e, runs) in enumerate(curves):
        for i, (t, r, s) in enumerate(runs):
            lab = e.label if i == 0 else None
            a1.plot(t, r, color=f"C{c}", lw=1, alpha=0.8, label=lab)
            a2.plot(t, np.maximum(s, 1e-4), color=f"C{c}", lw=1, alpha=0.8, label=lab)
    styles = {"zero": ":", "best_constant": "--", "feedback": "-."}
    for b in baselines:
        if b.key in styles:
            a1.axhline(b.scores.ret.mean(), color="k", ls=styles[b.key], lw=0.8, label=b.label)
            a2.axhline(max(b.scores.stick_fraction.mean(), 1e-4), color="k", ls=styles[b.key],
                       lw=0.8)
    lows = [b.scores.ret.mean() for b in baselines] + [r.min() for _, rs in curves
                                                          for _, r, _ in rs]
    a1.set_xlabel("training steps")
    a1.set_ylabel("episode return")
    a1.set_yscale("symlog", linthresh=10)
    a1.set_ylim(1.5 * min(lows), 0.0)
    a2.set_xlabel("training steps")
    a2.set_ylabel("stick-time fraction")
    a2.set_yscale("log")
    a1.set_title("deterministic evaluation during training (one line per seed)", fontsize=9)
    a2.set_title("baselines: final-evaluation means (black)", fontsize=9)
    a1.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True

def evaluate_scene(scene: str, args: argparse.Namespace,
                   trained: tuple[list[Entry], dict] | None = None,
                   stage: Callable[[str], None] | None = None) -> Path:
    """Evaluate and write ``scene``'s outputs; ``trained``: its entry of ``prepare``'s
    result (else the models are loaded here); ``stage``: called with a line per stage
    (and a progress bar over the episodes shows unless ``args.quiet``)."""
    from fricenv.progress import tqdm  # (its rate leaves out compile time)

    stage = stage or (lambda message: None)
    t0 = time.perf_counter()
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    trained_list, env_kwargs = trained or trained_entries([*args.runs, *args.models], scene)
    if getattr(args, "max_steps", None) is not None:
        env_kwargs = {**env_kwargs, "max_episode_steps": args.max_steps}
    names = [n for n in BASELINES if n in args.controllers]
    search = {"n_u0": args.grid, "n_nu": args.grid, "episodes": args.search_episodes}
    if "best_constant" in names:
        stage(f"{scene}: searching the best constant excitation ({args.grid} x {args.grid} "
              f"grid, {args.search_episodes} episodes per candidate; cache in {out})")
    baselines = baseline_entries(names, scene, env_kwargs, out, search)
    entries = baselines + trained_list
    stage(f"{scene}: running {len(entries)} controllers on {args.seeds} x {args.episodes} "
          "held-out episodes")
    batches = sum(len(e.factories) for e in entries) * args.seeds
    with tqdm(total=batches, unit="batch", desc=f"{scene} episodes", dynamic_ncols=True,
              disable=getattr(args, "quiet", False)) as bar:
        for e in entries:
            bar.set_postfix_str(e.label, refresh=True)
            run_entry(e, scene, env_kwargs, args.seeds, args.episodes, bar)

    plots: list[str] = []
    if not args.no_plots:
        stage(f"{scene}: drawing the time history and the learning curves")
        zero = ZeroExcitation(scene, env_kwargs)
        shown: list[tuple[str, Controller]] = [(zero.label, zero)]
        shown += [(e.label, e.factories[0](0)) for e in entries
                  if e.key in ("best_constant", "feedback")]
        shown += [(f"{e.label.split(' (')[0]} (training seed {e.info['seeds'][0]})",
                   e.factories[0](0)) for e in trained_list]
        name = f"{scene}_time_history.png"
        time_history(shown, scene, env_kwargs, eval_env_seed(0), out / name)
        plots.append(name)
        name = f"{scene}_learning_curves.png"
        if learning_curves(trained_list, baselines, out / name):
            plots.append(name)

    md = markdown(scene, entries, args.seeds, args.episodes, plots, env_kwargs)
    table = out / f"{scene}.md"
    table.write_text(md + "\n")
    result = {
        "scene": scene, "env_kwargs": env_kwargs, "n_seeds": args.seeds,
        "episodes": args.episodes, "eval_plant_seeds": eval_seeds(args.seeds, args.episodes),
        "seconds": round(time.perf_counter() - t0, 2),
        "controllers": {e.key: {**_summary(e), "info": e.info,
                                "per_episode": e.scores.as_dict(),
                                "seed_means": e.seed_means} for e in entries},
    }
    (out / f"{scene}_results.json").write_text(json.dumps(result, indent=1, default=str))
    print(md)
    return table
