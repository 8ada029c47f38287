"""The control benchmark's rows, conditions and scoring runs (``fricenv_agents.benchmark``
writes the page from what they score).

The rows and the scenes' evaluation live here, below the page (``benchmark``), its figures
(``benchmark_figures``) and its worker processes (``benchmark_workers``), which all import
them: the benchmark's modules form no import cycle (``tests/test_import_graph.py``).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fricenv.envs.scenes import SCENES, Scene

from . import statistics as S
from .layout import check_disjoint
from .mpc import MPPIController
from .rollouts import Controller
from .scoring import Entry, baseline_entries, load_models, run_entry, trained_entries

BENCH_SCENES = ("paper", "self_excited", "stribeck", "viscous")
#: Rough relative cost of a scene's evaluation (its MPC rows dominate; measured with
#: ``--jobs 1``): ``--jobs`` starts the costliest first.
SCENE_COST = {"stribeck": 24.0, "viscous": 14.0, "self_excited": 5.0, "paper": 1.0}
#: Folder of the shipped benchmark runs (``<group>_<scene>_s<seed>/``), the default ``--runs``.
PRETRAINED_RUNS = Path(__file__).resolve().parent / "pretrained" / "benchmark"
#: Parameters whose ranges the held-out plants leave, and by how much: a box from
#: ``GAP`` to ``GAP + WIDTH`` range widths beyond each end (lambda floored at 0).
HELD_OUT = ("lam", "xfs")
GAP, WIDTH = 0.1, 0.5
#: Sensor noise of the ``noise + delay`` condition (standard deviation per channel), also
#: what the robust PPO is trained with (its scale drawn per episode).
NOISE = {"x": 0.05, "v_rel": 0.05, "cos1": 0.02, "sin1": 0.02, "cos2": 0.02, "sin2": 0.02}
DELAY = 1
NOMINAL = "nominal"  #: the main table's condition: the scenes' own plants and sensors
CONDITIONS = ("in range", "held out below", "held out above", "noise + delay")
ALL_CONDITIONS = (NOMINAL, *CONDITIONS)
#: The retentions of the generalisation table: name -> the conditions whose worst cut is
#: compared with the in-range one.
RETENTIONS = {"retention, held out": ("held out below", "held out above"),
              "retention, noise + delay": ("noise + delay",)}
#: The robust PPO's largest training noise, in units of ``NOISE``: its episodes draw noise
#: scales below and above the benchmark's, which then lies inside what it trained on.
ROBUST_NOISE_FACTOR = 1.5
#: Training env kwargs of the robust PPO: randomised plants, and per episode a noise scale
#: uniform in [0, 1) of ``ROBUST_NOISE_FACTOR * NOISE`` and a delay in {0, 1}
#: (``randomize_sensors``).
ROBUST_ENV_KWARGS: dict[str, Any] = {
    "randomize": True,
    "obs_noise": {k: round(ROBUST_NOISE_FACTOR * v, 9) for k, v in NOISE.items()},
    "obs_delay": DELAY, "randomize_sensors": True}
#: The tables flag a learned controller more than this fraction of |MPC return| behind the
#: MPC, and one keeping less than ``RETENTION_BAR`` of its in-range stick cut.
GAP_BAR = 0.05
RETENTION_BAR = 0.8
#: Cuts and retentions compare mean stick fractions, i.e. shares of the total stuck time,
#: so that a rare episode that sticks much counts fully; the main tables' cells are IQMs.
CUT_AGGREGATE = S.mean
BOOT_SEED = 0  #: seed of every bootstrap of the page (its intervals are reproducible)


# -- the rows ---------------------------------------------------------------------------------
@dataclass
class Setting:
    """What a row's builder gets: the scene (``plant``: as run, a held-out variant in those
    conditions), the condition, its env kwargs and the benchmark's options."""

    scene: str
    plant: str | Scene
    condition: str
    env_kwargs: dict[str, Any]
    runs: Path
    out: Path
    search: dict[str, Any]
    n_seeds: int
    episodes: int
    cache: dict[str, Any] = field(default_factory=dict)  #: loaded models, shared per scene


@dataclass(frozen=True)
class Row:
    """One controller of the benchmark.

    ``build(setting)`` returns its entry for that scene and condition, or ``None`` to
    leave the row out there (a group without runs). ``conditions``: where it runs
    (``NOMINAL`` is the main table). ``label``: the tables' name (default: the entry's
    own; a trained group's gets its number of training seeds). ``train``: ``(algorithm,
    env kwargs)`` of a trained group, which ``scripts/train_control_benchmark.py`` trains
    into ``<runs>/<key>_<scene>_s<seed>``. ``retention_of``: see the field.
    """

    key: str
    short: str  #: name in the figures
    build: Callable[[Setting], Entry | None]
    conditions: tuple[str, ...] = (NOMINAL,)
    label: str | None = None
    train: tuple[str, dict[str, Any]] | None = None
    #: The row whose in-range stick cut the retentions divide by (default: this row's own):
    #: a controller made for noisy sensors only is measured against what its noise-free
    #: counterpart achieves.
    retention_of: str | None = None


def baseline(name: str) -> Callable[[Setting], Entry]:
    """Builder of a baseline of ``fricenv_agents.baselines`` (its settings fit the scene
    by name; a held-out variant has the same actions)."""
    def build(s: Setting) -> Entry:
        return baseline_entries([name], s.scene, s.env_kwargs, s.out, s.search)[0]

    return build


def per_seed(make: Callable[[Setting, int], Controller]) -> Callable[[Setting], Entry]:
    """Builder of a controller without training seeds: ``make(setting, k)`` is the
    controller of evaluation seed ``k`` (a randomised one seeds itself from ``k``; others
    may ignore it). The tables name it by its ``label`` attribute (else its class name);
    the JSON records its ``describe()`` if it has one."""
    def build(s: Setting) -> Entry:
        first = make(s, 0)
        describe = getattr(first, "describe", None)
        info = describe() if callable(describe) else {"class": type(first).__name__}
        label = str(getattr(first, "label", type(first).__name__))

        def factory(k: int) -> Controller:
            return first if k == 0 else make(s, k)

        return Entry("", label, "baseline", [factory], info)

    return build


def exact_mpc(s: Setting, k: int) -> MPPIController:
    """The exact-model MPC: bound to the plants' exact states, except under sensor noise,
    where it plans from the noisy, delayed observation."""
    return MPPIController(s.plant, s.env_kwargs, seed=k,
                          exact_state=s.condition != "noise + delay")


def filtered_mpc(s: Setting, k: int) -> Controller:
    """The same MPC behind a particle filter on the exact model
    (``fricenv_agents.estimation``): it plans from the filter's estimate, never from the
    plants' exact states."""
    from .estimation import FilteredMPC

    return FilteredMPC(s.plant, s.env_kwargs, seed=k)


def run_group(root: Path, group: str, scene: str) -> list[Path]:
    """Finished run folders of ``group`` (``ppo``, ``sac``, ``ppo_robust``) for ``scene``."""
    return sorted(p for p in root.glob(f"{group}_{scene}_s*") if (p / "model.zip").exists())


def trained(group: str) -> Callable[[Setting], Entry | None]:
    """Builder of a trained group's row: every model of ``<runs>/<group>_<scene>_s*``
    (loaded once per scene), or ``None`` without runs."""
    def build(s: Setting) -> Entry | None:
        if group not in s.cache:
            s.cache[group] = _load_group(s, group)
        e = s.cache[group]
        if e is None:
            return None
        return Entry(group, e.label, e.kind, e.factories, dict(e.info))

    return build


def _with_seeds(label: str, n: int) -> str:
    """``label`` with a trained group's number of training seeds."""
    seeds = f"{n} training seed{'s' if n > 1 else ''}"
    return label[:-1] + f"; {seeds})" if label.endswith(")") else f"{label} ({seeds})"


def _load_group(s: Setting, group: str) -> Entry | None:
    paths = run_group(s.runs, group, s.scene)
    if not paths:
        return None
    loaded = load_models(paths)
    for p, (_, cfg) in loaded.items():
        check_disjoint(cfg, s.n_seeds, s.episodes, str(p))
    entries, _ = trained_entries(paths, s.scene, loaded)
    if len(entries) != 1:
        raise ValueError(f"{s.runs}: the runs of group {group!r} on {s.scene!r} hold "
                         f"{len(entries)} algorithms ({[e.key for e in entries]}), expected one")
    return entries[0]


ZERO_LABEL = "zero excitation (paper: no control, u0 = 2 and nu = 0.1 held)"
ROWS: tuple[Row, ...] = (
    Row("zero", "zero", baseline("zero"), ALL_CONDITIONS, ZERO_LABEL),
    Row("random", "random", baseline("random")),
    Row("best_constant", "best constant", baseline("best_constant"), label="best constant"),
    Row("feedback", "feedback rule", baseline("feedback")),
    # (bound to the exact plant, parameters included, the MPC has no training range to
    # leave: the held-out boxes do not apply to it)
    Row("mpc", "MPC", per_seed(exact_mpc), (NOMINAL, "in range", "noise + delay")),
    Row("mpc_filter", "MPC + filter", per_seed(filtered_mpc), ("noise + delay",),
        retention_of="mpc"),
    Row("ppo", "PPO", trained("ppo"), ALL_CONDITIONS, "PPO", ("ppo", {})),
    Row("ppo_robust", "PPO, robust training", trained("ppo_robust"), ALL_CONDITIONS,
        "PPO, robust training (randomised plants and sensors)", ("ppo", ROBUST_ENV_KWARGS)),
    Row("sac", "SAC", trained("sac"), label="SAC", train=("sac", {})),
)


def training_groups(rows: Sequence[Row] = ROWS) -> dict[str, tuple[str, dict[str, Any]]]:
    """Group (run folder prefix) -> (algorithm, env kwargs) of every trained row."""
    return {r.key: r.train for r in rows if r.train is not None}


def check_rows(rows: Sequence[Row]) -> None:
    """``ValueError`` for two rows with one key, a row in an unknown condition, a
    condition without the ``zero`` row (the reference of the stick cuts), or a
    ``retention_of`` naming no row."""
    keys = [r.key for r in rows]
    if len(set(keys)) != len(keys) or "zero" not in keys:
        raise ValueError(f"rows need distinct keys and a 'zero' row (the stick cuts' "
                         f"reference), got {keys}")
    zero = next(r for r in rows if r.key == "zero")
    for r in rows:
        bad = set(r.conditions) - set(ALL_CONDITIONS)
        if bad:
            raise ValueError(f"row {r.key!r}: unknown conditions {sorted(bad)}; expected "
                             f"some of {list(ALL_CONDITIONS)}")
        if set(r.conditions) - set(zero.conditions):
            raise ValueError(f"row {r.key!r} runs in {list(r.conditions)}, the 'zero' row "
                             f"only in {list(zero.conditions)}")
        if r.retention_of is not None and r.retention_of not in keys:
            raise ValueError(f"row {r.key!r}: retention_of names no row: "
                             f"{r.retention_of!r}")


# -- running ----------------------------------------------------------------------------------
def held_out_scene(scene: str, side: str) -> Scene:
    """``scene`` with its ranges of ``HELD_OUT`` moved beyond their ``side`` ("below" or
    "above") end; the other randomised parameters keep their ranges."""
    sc = SCENES[scene]
    ranges = sc.ranges
    for key in HELD_OUT:
        lo, hi = ranges[key]
        w = hi - lo
        if side == "below":
            ranges[key] = (max(0.0, lo - (GAP + WIDTH) * w), lo - GAP * w)
        else:
            ranges[key] = (hi + GAP * w, hi + (GAP + WIDTH) * w)
    return sc.replace(name=f"{scene}_held_out_{side}", randomization=ranges)


def condition_setting(base: Setting, condition: str) -> Setting:
    """``base`` (the nominal setting of a scene) moved to ``condition``."""
    kw = dict(base.env_kwargs)
    plant: str | Scene = base.scene
    if condition != NOMINAL:
        kw["randomize"] = True
    if condition.startswith("held out"):
        plant = held_out_scene(base.scene, condition.split()[-1])
    if condition == "noise + delay":
        kw.update(obs_noise=NOISE, obs_delay=DELAY)
    return Setting(base.scene, plant, condition, kw, base.runs, base.out, base.search,
                   base.n_seeds, base.episodes, base.cache)


def evaluate_condition(rows: Sequence[Row], setting: Setting) -> dict[str, Entry]:
    """Every row of ``setting.condition`` on its episodes: key -> scored entry."""
    out: dict[str, Entry] = {}
    for row in rows:
        if setting.condition not in row.conditions:
            continue
        e = row.build(setting)
        if e is None:
            continue
        e.key = row.key
        if row.label:
            e.label = (_with_seeds(row.label, len(e.factories)) if e.kind == "trained"
                       else row.label)
        t = time.perf_counter()
        run_entry(e, setting.plant, setting.env_kwargs, setting.n_seeds, setting.episodes)
        e.info["eval_seconds"] = round(time.perf_counter() - t, 2)
        out[row.key] = e
    zero = out.get("zero")
    for e in out.values():
        what = f"return IQM {e.interval('ret').format()}"
        if zero is not None and setting.condition != NOMINAL:
            cut = _cut_stat(e.matrix("stick_fraction"), zero.matrix("stick_fraction"))
            what += f", stick cut {100 * float(cut):.1f} %"
        print(f"  {setting.scene:13s} {setting.condition:15s} {e.label[:40]:40s} {what}",
              flush=True)
    return out




# -- statistics of the scoring runs ---------------------------------------------------------------
def _cut_stat(ctrl: Any, zero: Any) -> Any:
    agg = S.cell_stat(CUT_AGGREGATE)
    return 1.0 - agg(ctrl) / agg(zero)



# -- results ---------------------------------------------------------------------------------
Results = dict[str, dict[str, Entry]]  #: scene -> row key -> entry (one condition)
Generalisation = dict[str, dict[str, dict[str, Entry]]]  #: scene -> condition -> key -> entry



def row_keys(rows: Sequence[Row], results: Results) -> list[str]:
    """Keys of the rows that ran somewhere, in the registry's order."""
    return [r.key for r in rows if any(r.key in res for res in results.values())]



def short_name(rows: Sequence[Row], key: str) -> str:
    return next((r.short for r in rows if r.key == key), key)




def evaluate_scene(scene: str, args: argparse.Namespace, rows: Sequence[Row] = ROWS,
                   ) -> tuple[dict[str, Entry], dict[str, dict[str, Entry]]]:
    """Every row of ``scene``: the main table's entries and the generalisation study's
    (condition -> entries; empty with ``--no-generalisation``)."""
    base = {} if args.max_steps is None else {"max_episode_steps": args.max_steps}
    search = {"n_u0": args.grid, "n_nu": args.grid, "episodes": args.search_episodes}
    nominal = Setting(scene, scene, NOMINAL, base, args.runs, args.out, search, args.seeds,
                      args.episodes)
    results = evaluate_condition(rows, nominal)
    gen = {}
    if not args.no_generalisation and any(c in r.conditions for r in rows
                                          if r.key != "zero" for c in CONDITIONS):
        gen = {c: evaluate_condition(rows, condition_setting(nominal, c)) for c in CONDITIONS}
    return results, gen
