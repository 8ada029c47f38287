"""Worker-side probes of the stress matrix's later classes (loaded by ``tests/callcheck.py``'s
worker next to its own entries: ``Worker(..., plugins=[this file])``).

Each entry takes plain data and returns either a list of what is wrong with an answer
(judged like the worker's own entries) or an outcome dict ``{"kind", "wrong", "error"}``
when the class has its own rule for errors: an error is *clear* only if it is a
``ValueError`` / ``TypeError`` that names the argument, file or store at fault; any other
exception (``RuntimeError: Zstd decompression error``, ``JSONDecodeError``, ``KeyError``,
``IndexError``...) is *bare*. The module imports nothing of the project but ``fricenv``
(and only through its public names and documented layouts), so the same probes judge any
tree that ``PYTHONPATH`` picks.
"""

from __future__ import annotations

import dataclasses
import math
import os
import resource
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

#: Variables of an atlas store (the Zarr arrays beside the coordinates).
ATLAS_VARS = ("label", "stick_fraction", "n_stick", "n_reversal", "v_min", "v_max", "period",
              "status")
#: Address space a probe that may allocate without bound gets beyond what the worker
#: holds (bytes): a refused allocation, not a machine out of memory, ends it.
MEMORY_HEADROOM = 6 * 2**30
#: Tolerances of an observation compared with a fresh environment's (the workspace's
#: constants differ in the last bits when recomputed; anything physical differs by far more).
OBS_RTOL, OBS_ATOL = 1e-6, 1e-9


def _error(e: BaseException, names: tuple[str, ...]) -> dict:
    """Clear if a ValueError/TypeError whose message holds one of ``names``, else bare."""
    text = f"{type(e).__name__}: {str(e)[:300]}"
    clear = isinstance(e, (ValueError, TypeError)) and any(n in str(e) for n in names)
    return {"kind": "clear" if clear else "bare", "wrong": [], "error": text}


def _returned(wrong: list[str]) -> dict:
    return {"kind": "returned", "wrong": wrong, "error": ""}


# -- atlas stores ---------------------------------------------------------------------------
def _atlas_call(path: Path | None, spec: dict) -> Any:
    import fricenv

    axes = {k: np.linspace(*v) for k, v in spec["axes"].items()}
    return fricenv.atlas(spec["base"], axes, path=path,
                         chunks=tuple(spec["chunks"]) if spec.get("chunks") else None,
                         progress=False)


def _values(ds: Any) -> dict[str, np.ndarray]:
    out = {k: np.asarray(ds[k].values) for k in ATLAS_VARS}
    out.update({k: np.asarray(ds[k].values) for k in ds.coords})
    return out


def _differences(got: dict[str, np.ndarray], want: dict[str, np.ndarray]) -> list[str]:
    bad = []
    for k, w in want.items():
        g = got.get(k)
        if g is None or g.shape != w.shape or not np.array_equal(
                g, w, equal_nan=w.dtype.kind == "f"):
            n = "?" if g is None or g.shape != w.shape else int(np.sum(
                ~((g == w) | (np.isnan(g) & np.isnan(w)) if w.dtype.kind == "f" else g == w)))
            bad.append(f"{k} ({n} values)")
    return [f"values differ from the undamaged store's: {', '.join(bad)}"] if bad else []


def _damage(store: Path, damage: dict) -> None:
    """Apply one damage to a copy of a store (see :func:`atlas_damage`)."""
    kind, target = damage["kind"], store / damage["file"]
    if kind == "flip":
        data = bytearray(target.read_bytes())
        data[damage["offset"] % len(data)] ^= 1 << damage["bit"]
        target.write_bytes(bytes(data))
    elif kind == "delete":
        target.unlink()
    elif kind == "truncate":
        target.write_bytes(target.read_bytes()[: len(target.read_bytes()) // 2])
    elif kind == "garbage":
        target.write_text("{not json")
    elif kind == "shape":
        import json

        meta = json.loads(target.read_text())
        meta["shape"] = [s + 3 for s in meta["shape"]]
        target.write_text(json.dumps(meta))
    else:
        raise AssertionError(kind)


def atlas_damage(good: str, spec: dict, damage: dict, action: str) -> dict:
    """A copy of the atlas store ``good`` (made by ``fricenv.atlas(**spec)``) with one
    damage, then opened (``action="open"``: ``open_atlas(path).load()``) or resumed
    (``"resume"``: the same ``atlas`` call). Wrong: values that differ from the undamaged
    store's with no error; clear: a ValueError naming the store; sound: equal values."""
    import fricenv

    want = _values(fricenv.open_atlas(good).load())
    with tempfile.TemporaryDirectory() as tmp:
        store = Path(tmp) / "damaged.zarr"
        shutil.copytree(good, store)
        _damage(store, damage)
        try:
            if action == "open":
                ds = fricenv.open_atlas(store).load()
            else:
                ds = _atlas_call(store, spec).load()
            return _returned(_differences(_values(ds), want))
        except Exception as e:  # noqa: BLE001  (judged, not handled)
            return _error(e, (str(store), store.name))


def atlas_huge(axes: dict, path: bool = False) -> dict:
    """``fricenv.atlas`` over a grid too large to compute: a prompt ValueError (or
    TypeError) is clear, a MemoryError bare (the worker's memory is capped meanwhile)."""
    import fricenv

    grid = {k: np.linspace(*v) for k, v in axes.items()}
    with tempfile.TemporaryDirectory() as tmp, _memory_cap():
        try:
            fricenv.atlas("coulomb", grid, path=Path(tmp) / "a.zarr" if path else None,
                          progress=False)
        except Exception as e:  # noqa: BLE001
            return _error(e, ("",))  # (any ValueError: a refused size names no one axis)
    return _returned(["an atlas of this size returned"])


class _memory_cap:
    """Cap the worker's address space at its size now plus ``MEMORY_HEADROOM`` (undone on
    exit), so that a call allocating without bound fails with MemoryError instead of
    taking the machine's memory."""

    def __enter__(self) -> None:
        self.old = resource.getrlimit(resource.RLIMIT_AS)
        size = int(Path("/proc/self/statm").read_text().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        resource.setrlimit(resource.RLIMIT_AS, (size + MEMORY_HEADROOM, self.old[1]))

    def __exit__(self, *exc: object) -> None:
        resource.setrlimit(resource.RLIMIT_AS, self.old)


# -- the environment's plant state ----------------------------------------------------------
def _plant_index(field: str, k: int = 0) -> int:
    from fricenv import layout, params
    from fricenv.envs import state

    if field in ("t", "x", "v", "mode"):
        return state.PL_S + getattr(layout, f"S_{field.upper()}")
    if field == "xfs":
        return state.PL_P + params.P_XFS
    if field == "work":
        return state.PL_WORK + k
    raise AssertionError(field)


def _steps(env: Any, n: int) -> tuple[list[np.ndarray], list[float]]:
    obs, times = [], []
    a = np.zeros(env.action_space.shape, np.float32)
    for _ in range(n):
        obs.append(np.asarray(env.step(a)[0], float))
        times.append(env.get_state().t)
    return obs, times


def set_state(env_id: str, change: dict, steps: int = 3) -> dict:
    """``set_state`` of a state with ``change`` (plant-vector fields: ``t, x, v, mode,
    xfs``; ``work``: every workspace slot set to a value, or ``work_slot``: ``(fraction,
    value)``, the slot at that fraction of the workspace), then ``steps`` zero-action
    steps. Wrong if accepted and a step raises, the observations differ from those of the
    reference, the time does not advance or a value is non-finite. The
    reference: for a physical change, a fresh ``reset`` to that plant, position, speed and
    phases (a state that ``reset`` refuses and ``set_state`` accepts is wrong too); for
    ``t`` and the workspace, the unchanged state stepped alike."""
    import gymnasium as gym

    import fricenv  # noqa: F401  (registers the ids)

    env = gym.make(env_id).unwrapped
    env.reset(seed=0)
    base = env.get_state()
    plant = base.plant.copy()
    work_slots = plant.size - _plant_index("work")
    for k, value in change.items():
        if k == "work":
            idx = [_plant_index("work", j) for j in range(work_slots)]
        elif k == "work_slot":  # (at this fraction of the workspace's length)
            value, idx = value[1], [_plant_index("work", int(value[0] * work_slots))]
        else:
            idx = [_plant_index(k)]
        plant[idx] = value
    try:  # (a PlantState that checks itself may refuse the change already)
        state = dataclasses.replace(base, plant=plant)
        env.set_state(state)
    except Exception as e:  # noqa: BLE001
        return _error(e, ("state", *change))
    try:
        obs, times = _steps(env, steps)
    except Exception as e:  # noqa: BLE001
        return _returned([f"accepted, then step raised {type(e).__name__}: {str(e)[:200]}"])
    wrong = []
    if not all(np.all(np.isfinite(o)) for o in obs):
        wrong.append("non-finite observation after an accepted state")
    if not (times[0] > state.t and np.all(np.diff(times) > 0)):
        wrong.append(f"time does not advance from t = {state.t!r}: {times}")
    ref = gym.make(env_id).unwrapped
    if set(change) & {"x", "v", "mode", "xfs"}:
        p = state.params
        options = {k: p[k] for k in ("lam", "eta", "V", "xfk", "xfs", "b1", "b3", "u0", "nu")}
        options.update(x0=state.x, v0=state.v, phi1=state.phases[0], phi2=state.phases[1])
        try:
            ref.reset(seed=0, options=options)
        except Exception as e:  # noqa: BLE001
            return _returned([*wrong, f"accepted a state that reset refuses "
                              f"({type(e).__name__}: {str(e)[:120]})"])
    else:
        ref.reset(seed=0)
        ref.set_state(base)
    want = _steps(ref, steps)[0]
    if not all(np.allclose(o, w, rtol=OBS_RTOL, atol=OBS_ATOL) for o, w in zip(obs, want,
                                                                                 strict=True)):
        wrong.append(f"observations differ from the reference's: {obs[-1].tolist()} "
                     f"vs {want[-1].tolist()}")
    return _returned(wrong)


# -- output points --------------------------------------------------------------------------
def output_points(t_span: float, dt_out: float, t0: float = 0.0) -> dict:
    """``simulate(OscillatorParams(u0=1.5), t_span, dt_out=...)`` from ``t0`` (under a
    memory cap). Wrong: output times not strictly increasing, a non-finite trajectory, or
    a SimulationError that blames stiffness (the plant is not stiff); clear: a ValueError
    or another documented error; bare: MemoryError or anything else."""
    import fricenv

    p = fricenv.OscillatorParams(u0=1.5)
    try:
        with _memory_cap():
            tr = fricenv.simulate(p, t_span, state=fricenv.OscillatorState.start(p, t0=t0),
                                  dt_out=dt_out)
            t = np.asarray(tr.t)
            wrong = [] if np.all(np.diff(t) > 0) else [
                f"output times not strictly increasing ({int(np.sum(np.diff(t) <= 0))} of "
                f"{t.size - 1} steps)"]
            if not (np.all(np.isfinite(tr.x)) and np.all(np.isfinite(tr.v))):
                wrong.append("non-finite trajectory")
            del tr, t
        return _returned(wrong)
    except Exception as e:  # noqa: BLE001
        if isinstance(e, fricenv.SimulationError) and "stiff" in str(e):
            return _returned([f"a non-stiff plant blamed as stiff: {str(e)[:200]}"])
        kind = "clear" if isinstance(e, (ValueError, TypeError, RuntimeError)) else "bare"
        return {"kind": kind, "wrong": [], "error": f"{type(e).__name__}: {str(e)[:300]}"}


# -- tampered map files ---------------------------------------------------------------------
_MAP = {"u0": [0.5, 3.0], "nu": [0.5, 1.3]}


#: The tampered maps' changes: (array, cell or everything, value).
_TAMPER = {"stats_inf": ("stats", (0, 0), np.inf), "stats_nan": ("stats", ..., np.nan),
           "period": ("period", (0, 0), -3), "status": ("status", (0, 0), 77),
           "label": ("labels", (0, 0), 99)}


def _tampered(m: Any, change: str) -> Any:
    """A copy of map ``m`` with ``change`` made (in copies of its arrays)."""
    name, where, value = _TAMPER[change]
    arr = getattr(m, name).copy()
    arr[where] = value
    return dataclasses.replace(m, **{name: arr})


def tampered_map(change: str, action: str) -> dict:
    """A regime map saved with ``path=``, loaded, changed (``change``) and saved again with
    the package's own ``save`` (valid format and checksums), then loaded (``action="load"``)
    or resumed (``"resume"``). Wrong: it loads, or the resumed map keeps the values;
    clear: a ValueError naming the file."""
    import fricenv

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "m.npz"
        good = fricenv.regime_map("coulomb", _MAP["u0"], _MAP["nu"], path=path,
                                  progress=False)
        try:  # (a map that checks itself may refuse the change, or its save)
            _tampered(fricenv.RegimeMap.load(path), change).save(path)
            if action == "load":
                fricenv.RegimeMap.load(path)
                return _returned([f"a map with {change} tampered loads"])
            again = fricenv.regime_map("coulomb", _MAP["u0"], _MAP["nu"], path=path,
                                       progress=False)
        except Exception as e:  # noqa: BLE001
            return _error(e, (str(path), path.name))
        same = all(np.array_equal(getattr(again, k), getattr(good, k), equal_nan=True)
                   for k in ("stats", "period", "status", "labels"))
        return _returned([] if same else [f"the resumed map keeps the tampered {change}"])


# -- errors that should name what is wrong ---------------------------------------------------
def _render_mode() -> None:
    import gymnasium as gym

    gym.make("fricenv/StickSlip-v0", render_mode=5)


def _nan_mode_run() -> None:
    import fricenv

    p = fricenv.OscillatorParams(u0=1.0)
    fricenv.run_stats(p, 10.0, state=fricenv.OscillatorState(mode=math.nan))


def unclear(case: str) -> dict:
    """Calls with one bad argument; clear only if a ValueError/TypeError names it (the
    value or the argument), bare otherwise (for ``RegimeMap.load`` of an existing ``.npy``
    file, a FileNotFoundError is bare: the file is there)."""
    import fricenv

    State = fricenv.OscillatorState
    with tempfile.TemporaryDirectory() as tmp:
        npy = Path(tmp) / "x.npy"
        np.save(npy, np.arange(3.0))
        call, names = {
            "from_array_short": (lambda: State.from_array(np.array([1.0])),
                                 ("shape", "length", "size", "values", "(1,)", "got 1", "6")),
            "from_array_nan_mode": (
                lambda: State.from_array(np.array([0.0, 0.0, 0.0, np.nan, 0.0, 0.0])),
                ("mode",)),
            "state_nan_mode": (_nan_mode_run, ("mode",)),
            "load_npy": (lambda: fricenv.RegimeMap.load(npy), (f"{npy}'", f"{npy}:",
                                                               f"{npy} ", ".npy file")),
            "render_mode": (_render_mode, ("render_mode",)),
        }[case]
        try:
            call()
        except Exception as e:  # noqa: BLE001
            if case == "load_npy" and isinstance(e, FileNotFoundError):
                return {"kind": "bare", "wrong": [], "error": f"{type(e).__name__}: {e}"}
            return _error(e, names)
    return _returned([f"{case}: accepted"])


def atlas_warm() -> list[str]:
    """A one-cell atlas: imports Dask, Zarr and xarray before any call is timed."""
    import fricenv

    fricenv.atlas("coulomb", {"u0": [1.0], "nu": [0.5]}, progress=False)
    return []


ENTRIES = {"atlas_warm": atlas_warm, "atlas_damage": atlas_damage, "atlas_huge": atlas_huge,
           "set_state": set_state, "output_points": output_points, "tampered_map": tampered_map,
           "unclear": unclear}
