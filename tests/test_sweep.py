"""Regime-map sweeps: determinism across chunking and threads, resume, storage, bad input."""

from __future__ import annotations

import json
from fractions import Fraction

import numba
import numpy as np
import pytest

from fricenv.layout import N_STATS, STATUS_OK
from fricenv.maps import _RESERVED_META
from fricenv.params import OscillatorParams
from fricenv.regimes import Regime
from fricenv.sweep import (
    NOT_COMPUTED,
    RegimeMap,
    SweepSettings,
    cell_statistics,
    modulation_period,
    plan_cells,
    regime_map,
)

PARAMS = OscillatorParams.preset("coulomb")  # eta = 3/5
U0 = np.array([0.3, 1.5, 4.0, 30.0])
NU = np.array([0.25, 0.5, 1.0, 1.3, 2.0])


def _same(a: RegimeMap, b: RegimeMap) -> None:
    for name in ("labels", "stats", "period", "status", "done", "q"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.fixture(scope="module")
def reference() -> RegimeMap:
    return regime_map(PARAMS, U0, NU, progress=False)


def test_map_contents(reference: RegimeMap) -> None:
    m = reference
    assert m.labels.shape == (4, 5) and m.stats.shape == (4, 5, N_STATS)
    assert m.complete and np.all(m.status == STATUS_OK)
    assert np.all(m.labels != NOT_COMPUTED)
    # the u0 pattern of docs/model.md: no contact -> stick phases -> reversals only
    assert m.labels[0, 0] == Regime.WM1 and m.labels[0, 3] == Regime.WM1
    assert m.labels[2, 0] == Regime.SSM1 and m.labels[2, 3] == Regime.SSM2
    assert m.labels[3, 0] == Regime.WM2
    # integer nu gets the periodic labels, with stick inside the band
    assert m.labels[0, 2] == Regime.PERIODIC_OSCILLATION
    assert m.labels[2, 2] == Regime.PERIODIC_STICK_SLIP
    assert list(m.q) == [4, 2, 1, 0, 1]
    # the window covers whole common periods of the forcing when periodicity is tested
    dur = m.stats[0, :, 0]
    t1 = 2 * np.pi / PARAMS.eta
    for j in (0, 1, 2, 4):
        k = dur[j] / (m.q[j] * t1)
        assert k == pytest.approx(round(k), rel=1e-9) and round(k) >= 12


def test_cells_equal_single_runs(reference: RegimeMap) -> None:
    ps = [PARAMS.replace(u0=float(U0[i]), nu=float(NU[j])) for i in (1, 2) for j in (0, 3)]
    labels, stats, period, status = cell_statistics(ps)
    got = reference.labels[np.ix_([1, 2], [0, 3])].ravel()
    np.testing.assert_array_equal(labels, got)
    np.testing.assert_array_equal(stats, reference.stats[np.ix_([1, 2], [0, 3])].reshape(4, -1))


@pytest.mark.parametrize("chunk_size", [1, 3, 7])
def test_identical_for_any_chunking(reference: RegimeMap, chunk_size: int) -> None:
    _same(reference, regime_map(PARAMS, U0, NU, chunk_size=chunk_size, progress=False))


def test_identical_for_any_thread_count(reference: RegimeMap) -> None:
    before = numba.get_num_threads()
    for n in range(1, numba.config.NUMBA_NUM_THREADS + 1):
        _same(reference, regime_map(PARAMS, U0, NU, n_threads=n, chunk_size=5,
                                    progress=False))
    assert numba.get_num_threads() == before  # restored


def test_identical_for_reordered_grid(reference: RegimeMap) -> None:
    m = regime_map(PARAMS, U0[::-1], NU[::-1], progress=False)
    np.testing.assert_array_equal(m.labels[::-1, ::-1], reference.labels)
    np.testing.assert_array_equal(m.stats[::-1, ::-1], reference.stats)


class _Interrupt(Exception):
    pass


def test_resume_after_interrupt(tmp_path, reference: RegimeMap) -> None:
    path = tmp_path / "map.npz"
    seen: list[int] = []

    def stop_after_two(m: RegimeMap, n_new: int) -> None:
        seen.append(n_new)
        if len(seen) == 2:
            raise _Interrupt

    with pytest.raises(_Interrupt):
        regime_map(PARAMS, U0, NU, path=path, chunk_size=3, callback=stop_after_two,
                   progress=False)
    part = RegimeMap.load(path)
    assert part.done.sum() == 6 and not part.complete
    np.testing.assert_array_equal(part.labels[part.done], reference.labels[part.done])
    assert np.all(part.labels[~part.done] == NOT_COMPUTED)

    new: list[int] = []
    full = regime_map(PARAMS, U0, NU, path=path, chunk_size=3,
                      callback=lambda m, n: new.append(n), progress=False)
    assert sum(new) == U0.size * NU.size - 6  # finished cells are not recomputed
    _same(reference, full)
    _same(reference, RegimeMap.load(path))
    # a finished map resumes without any work
    again: list[int] = []
    regime_map(PARAMS, U0, NU, path=path, callback=lambda m, n: again.append(n),
               progress=False)
    assert again == []


def test_resume_refuses_other_arguments(tmp_path) -> None:
    path = tmp_path / "m.npz"
    regime_map(PARAMS, U0[:2], NU[:2], path=path, progress=False)
    with pytest.raises(ValueError, match="other parameters"):
        regime_map(PARAMS.replace(eta=0.7), U0[:2], NU[:2], path=path, progress=False)
    with pytest.raises(ValueError, match="other parameters"):
        regime_map(PARAMS, U0[:2], NU[:2], path=path, progress=False, window_min=150.0)
    with pytest.raises(ValueError, match="other parameters"):
        regime_map(PARAMS, U0[:3], NU[:2], path=path, progress=False)
    m = regime_map(PARAMS, U0[:3], NU[:2], path=path, resume=False, progress=False)
    assert m.complete and RegimeMap.load(path).labels.shape == (3, 2)


def test_storage_roundtrip_and_metadata(tmp_path, reference: RegimeMap) -> None:
    path = reference.save(tmp_path / "r")  # suffix added
    assert path.name == "r.npz"
    back = RegimeMap.load(path)
    _same(reference, back)
    assert back.params == PARAMS.replace(u0=0.0)  # the grid replaces u0 and nu
    assert back.settings == reference.settings
    np.testing.assert_array_equal(back.u0, U0)
    np.testing.assert_array_equal(back.plan.t_transient, reference.plan.t_transient)
    np.testing.assert_array_equal(back.plan.tries, [1, 1, 4, 0, 4])  # nu = 1/4, 1/2, 1, ., 2
    with np.load(path) as z:
        meta = json.loads(str(z["meta"][()]))
    assert meta["format"] == "fricenv.regime_map"
    assert meta["regimes"]["SSM2"] == int(Regime.SSM2)
    assert meta["settings"]["x0"] == 0.0 and meta["params"]["eta"] == PARAMS.eta
    assert len(meta["stats_layout"]) == N_STATS
    np.savez(tmp_path / "other.npz", a=np.zeros(2))
    with pytest.raises(ValueError, match="not a fricenv regime map"):
        RegimeMap.load(tmp_path / "other.npz")
    (tmp_path / "text.npz").write_text("no archive")
    with pytest.raises(ValueError, match="text.npz is not a fricenv regime map"):
        RegimeMap.load(tmp_path / "text.npz")
    # a wrong path is the error it is, not a file called a bad map
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        RegimeMap.load(tmp_path / "missing")
    (tmp_path / "folder.npz").mkdir()
    with pytest.raises(IsADirectoryError):
        RegimeMap.load(tmp_path / "folder.npz")


def test_other_friction_laws_run() -> None:
    for law in ("viscous", "stribeck"):
        m = regime_map(law, [0.2, 3.0], [0.5, 1.5], progress=False)
        assert m.complete and np.all(m.status == STATUS_OK)
        assert m.labels[0, 0] == Regime.WM1 and m.labels[1, 1] == Regime.SSM2


def test_progress_bar(capsys) -> None:
    regime_map(PARAMS, U0[:2], NU[:2], progress=True)
    assert "cell" in capsys.readouterr().err


def test_plan_uses_modulation_period() -> None:
    s = SweepSettings()
    t1 = 2 * np.pi / 0.6
    tm = modulation_period(0.6, np.array([0.1, 0.5, 0.98, 1.0, 2.25, 0.0]), s.modulation_cap)
    np.testing.assert_allclose(tm, t1 * np.array([10, 2, 50, 1, 4, 1]), rtol=1e-9)
    assert modulation_period(0.6, np.array([1 + 1e-9]), 100.0)[0] == pytest.approx(100 * t1)
    plan = plan_cells(PARAMS, np.array([0.1, 0.98, 3.0]), s)
    assert plan.t_transient[1] == pytest.approx(50 * t1)  # a full beat period
    assert plan.t_transient[2] == pytest.approx(100.0)  # 25 e-foldings at lambda = 1/2
    assert plan.n_segment[2] * plan.t_segment[2] >= 100.0


@pytest.mark.parametrize("kwargs, error", [
    (dict(u0=[], nu=[0.5]), ValueError),
    (dict(u0=[1.0], nu=np.array([])), ValueError),
    (dict(u0=[1.0, np.nan], nu=[0.5]), ValueError),
    (dict(u0=[1.0], nu=[0.5, np.inf]), ValueError),
    (dict(u0=[-1.0], nu=[0.5]), ValueError),
    (dict(u0=[1.0, 1e13], nu=[0.5]), ValueError),  # beyond PARAM_LIMIT
    (dict(u0=[1.0], nu=[0.5, 1e200]), ValueError),
    (dict(u0=[[1.0, 2.0]], nu=[0.5]), ValueError),
    (dict(u0=["a"], nu=[0.5]), TypeError),  # not numbers: the wrong type
    (dict(u0=[1.0, 5.0, 5.0], nu=[0.5]), ValueError),  # computed twice, then unplottable
])
def test_bad_grid_raises(kwargs: dict, error: type) -> None:
    with pytest.raises(error):
        regime_map(PARAMS, progress=False, **kwargs)


def test_bad_law_and_settings_raise() -> None:
    with pytest.raises(ValueError, match="unknown friction law"):
        regime_map("dry-ice", [1.0], [0.5])
    with pytest.raises(TypeError, match=r"params must be OscillatorParams .* got 42 \(int\)"):
        regime_map(42, [1.0], [0.5])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="Coulomb"):
        regime_map("stribeck", [1.0], [0.5], method="exact")
    with pytest.raises(ValueError):
        regime_map(PARAMS, [1.0], [0.5], method="magic")
    with pytest.raises(ValueError):
        regime_map(PARAMS, [1.0], [0.5], window_min=0.0)
    with pytest.raises(ValueError, match="unknown setting"):
        regime_map(PARAMS, [1.0], [0.5], no_such_setting=1.0)
    with pytest.raises(ValueError, match="'rk4'"):  # sweeps are event-driven only
        regime_map(PARAMS, [1.0], [0.5], method="rk4")
    with pytest.raises(ValueError, match="rtol"):  # a zero target would stall the steps
        regime_map(PARAMS, [1.0], [0.5], rtol=0.0)
    with pytest.raises(ValueError, match="reserved"):  # the map's own metadata
        regime_map(PARAMS, [1.0], [0.5], meta={"format": "x"})
    own = regime_map(PARAMS, [1.0], [0.5], progress=False).metadata()
    assert set(own) == _RESERVED_META  # every key the map writes is reserved, and no other
    with pytest.raises(ValueError, match=r"params\[1\]"):  # was run as 'event' silently
        cell_statistics([PARAMS, OscillatorParams.preset("stribeck")], method="exact")
    with pytest.raises(ValueError):
        regime_map(PARAMS, [1.0], [0.5], chunk_size=0)
    with pytest.raises(ValueError):
        regime_map(PARAMS, [1.0], [0.5], n_threads=numba.config.NUMBA_NUM_THREADS + 1)


def test_settings_of_wrong_type_raise_type_error() -> None:
    msg = r"settings must be a fricenv\.SweepSettings or None .* got \{\} \(dict\)"
    with pytest.raises(TypeError, match=msg):  # was AttributeError: no 'method_code'
        regime_map(PARAMS, [1.0], [0.5], settings={})  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=msg):
        cell_statistics([PARAMS], settings={})  # type: ignore[arg-type]


def test_meta_that_is_not_json_is_refused_before_any_cell_runs(tmp_path) -> None:
    path = tmp_path / "m.npz"
    with pytest.raises(TypeError, match="meta must hold JSON-able values"):
        regime_map(PARAMS, [1.0], [0.5], path=path, meta={"a": object()})
    assert list(tmp_path.iterdir()) == []  # no map, no temporary file


def test_sweeps_whose_cells_would_scan_for_hours_are_refused(tmp_path) -> None:
    """eta = 1e8 asks for ~1e11 scan steps a cell; that used to run without a word."""
    fast = PARAMS.replace(eta=1e8)
    path = tmp_path / "fast.npz"
    msg = r"5.657e\+10 scan steps over a span of 200 .*nu \* eta = 1.4142e\+08.*transient_efolds"
    with pytest.raises(ValueError, match=msg):
        regime_map(fast, [0.0, 1.0], [0.7071, 1.4142], path=path)  # no strobe (q > 4)
    assert not path.exists()  # refused before anything was written
    with pytest.raises(ValueError, match=r"scan steps .*eta = 1e\+08"):
        cell_statistics([fast.replace(u0=1.0, nu=0.7071)])
    # silent tones do not bound the step, but 1e9 strobe samples a cell would fill memory
    with pytest.raises(ValueError, match=r"would keep 1\d{9} stroboscopic samples"):
        cell_statistics([fast.replace(u0=0.0, nu=1.0)])


def test_cell_statistics_entries_must_be_oscillator_params() -> None:
    with pytest.raises(TypeError, match=r"params\[0\] must be an OscillatorParams, got \{\} "
                                        r"\(dict\)"):
        cell_statistics([{}])  # type: ignore[list-item]
    with pytest.raises(TypeError, match=r"params\[1\] must be an OscillatorParams, got 'coulomb'"):
        cell_statistics([PARAMS, "coulomb"])  # type: ignore[list-item]
    with pytest.raises(TypeError, match=r"params must be a list of OscillatorParams"):
        cell_statistics(PARAMS)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="params is empty"):
        cell_statistics([])
    p = PARAMS.replace(u0=0.3, nu=0.5)
    got = cell_statistics(iter([p]))  # an iterator used to be consumed early: no rows
    for a, b in zip(got, cell_statistics([p]), strict=True):
        np.testing.assert_array_equal(a, b)
    assert got[0].shape == (1,)


def test_integer_and_dict_arguments_of_wrong_type_raise_type_error() -> None:
    with pytest.raises(TypeError, match=r"chunk_size must be an integer, got 2\.0"):
        regime_map(PARAMS, [1.0], [0.5], chunk_size=2.0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"n_threads must be an integer, got 1\.5"):
        regime_map(PARAMS, [1.0], [0.5], n_threads=1.5)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"meta must be a dict or None, got \['x'\] \(list\)"):
        regime_map(PARAMS, [1.0], [0.5], meta=["x"])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"u0 must be an array of real numbers, got None"):
        regime_map(PARAMS, None, [0.5])  # was "u0 grid contains NaN"



@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        # counts given as floats were silently accepted (n_strobe=12.0, m_max=2.0)
        (dict(n_strobe=12.0), TypeError, r"n_strobe must be an integer, got 12\.0 \(float\)"),
        (dict(m_max=2.0), TypeError, r"m_max must be an integer, got 2\.0 \(float\)"),
        (dict(q_max=np.float64(4)), TypeError, r"q_max must be an integer, got np\.float64"),
        (dict(lock_extensions=True), TypeError, r"lock_extensions must be an integer, got True"),
        (dict(n_strobe=-1), ValueError, r"n_strobe must be an integer >= 0, got -1"),
        # a non-number was a ValueError; NaN, inf and out-of-range values still are
        (dict(rtol=None), TypeError, r"rtol must be a real number, got None \(NoneType\)"),
        (dict(window_min="100"), TypeError, r"window_min must be a real number, got '100'"),
        (dict(x0=float("nan")), ValueError, r"x0 must be finite, got nan"),
        (dict(window_min=0.0), ValueError, r"window_min must be > 0, got 0\.0"),
        (dict(atol=0.0), ValueError, r"atol must be > 0, got 0\.0"),  # as run_stats
        (dict(strobe_tol=1.0), ValueError, r"strobe_tol must be < 1, got 1\.0"),
        (dict(method=["exact"]), TypeError, r"method must be 'auto', 'exact' or 'event', got \["),
        (dict(method="magic"), ValueError, r"method must be 'auto', 'exact' or 'event', got 'mag"),
    ],
)
def test_sweep_settings_type_and_value_errors(kwargs: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        SweepSettings(**kwargs)
    with pytest.raises(error, match=match):  # the same through a sweep's keyword overrides
        regime_map(PARAMS, [1.0], [0.5], progress=False, **kwargs)
    assert SweepSettings(n_strobe=np.int64(12), m_max=2).n_strobe == 12  # numpy ints are ints


def test_grid_and_flag_arguments_of_wrong_type_raise_type_error() -> None:
    with pytest.raises(TypeError, match=r"nu must be an array of real numbers, got \['0\.5'\]"):
        regime_map(PARAMS, [1.0], ["0.5"])  # was parsed as a number
    with pytest.raises(TypeError, match=r"u0 must be an array of real numbers, got \[True\]"):
        regime_map(PARAMS, [True], [0.5])
    with pytest.raises(TypeError, match=r"resume must be a bool .* got 'no' \(str\)"):
        regime_map(PARAMS, [1.0], [0.5], resume="no")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"progress must be a bool .* got 1 \(int\)"):
        regime_map(PARAMS, [1.0], [0.5], progress=1)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"u0 must be an array of real numbers, got \[\[1"):
        regime_map(PARAMS, [[1.0], [1.0, 2.0]], [0.5])  # ragged: numbers, but no grid
    m = regime_map(PARAMS, [Fraction(1, 2)], np.array([1, 2]), progress=False)
    assert m.u0.tolist() == [0.5] and m.nu.tolist() == [1.0, 2.0]


def test_slowly_converging_orbit_locks_with_extensions() -> None:
    # Coulomb + viscosity slips with damping lam - b1 = 0.3: one transient is not enough to
    # reach the 1e-6 strobe tolerance here, repeated windows are
    p = OscillatorParams.preset("viscous", eta=5 / 3)
    lock = regime_map(p, [0.137], [1.0], progress=False, transient_min=60.0,
                      transient_efolds=0.0)
    once = regime_map(p, [0.137], [1.0], progress=False, transient_min=60.0,
                      transient_efolds=0.0, lock_extensions=0)
    assert lock.labels[0, 0] == Regime.PERIODIC_OSCILLATION and lock.period[0, 0] == 1
    assert once.labels[0, 0] == Regime.WM1 and once.period[0, 0] == 0


# -- input checks of the engine and the map files (each was silent or a bare traceback) -----
def test_run_cells_checks_what_its_kernel_would_not() -> None:
    """Short span arrays were read past their end, METHOD_EXACT ran a Stribeck row as the
    Coulomb plant, and NaN or negative spans gave empty windows with status OK."""
    from fricenv.layout import METHOD_EVENT, METHOD_EXACT
    from fricenv.sweep import run_cells

    s = SweepSettings()
    P = np.stack([PARAMS.replace(u0=1.0).to_array()] * 3)
    ok = (np.full(3, 10.0), np.full(3, 5.0), np.full(3, 2), np.zeros(3, np.int64))
    stats, status, _ = run_cells(P, *ok, s, METHOD_EXACT)
    assert np.all(status == STATUS_OK)
    assert np.all(np.isnan(stats[:, 9]))  # (v - V)^2 is skipped: NaN, not a measured 0
    cases = [
        ((P, np.full(2, 10.0), *ok[1:]), METHOD_EXACT, "t_transient must have one entry"),
        ((P, ok[0], np.array([5.0, np.nan, 5.0]), *ok[2:]), METHOD_EXACT, "cell 1: need"),
        ((P, np.array([10.0, 10.0, -1.0]), *ok[1:]), METHOD_EXACT, "cell 2: need"),
        ((P[:, :4], *ok), METHOD_EXACT, r"P_cells must have shape \(n, 12\)"),
        ((P, *ok), 7, "method must be METHOD_EXACT"),
    ]
    stribeck = P.copy()
    stribeck[1] = OscillatorParams.preset("stribeck", u0=1.0).to_array()
    cases.append(((stribeck, *ok), METHOD_EXACT, "cell 1: METHOD_EXACT needs the Coulomb"))
    for args, method, match in cases:
        with pytest.raises(ValueError, match=match):
            run_cells(*args, s, method)
    run_cells(stribeck, *ok, s, METHOD_EVENT)


def test_map_stats_mark_the_skipped_integral(reference: RegimeMap) -> None:
    assert np.all(np.isnan(reference.stats[..., 9]))
    assert np.isnan(cell_statistics([PARAMS.replace(u0=1.0)])[1][0, 9])


def test_loading_something_else_than_a_map_is_a_value_error(tmp_path) -> None:
    partial = tmp_path / "partial.npz"
    np.savez(partial, meta=np.array(json.dumps({"format": "fricenv.regime_map",
                                                "version": 1})), u0=U0)
    notes = tmp_path / "notes.npz"
    notes.write_text("not an archive")
    for path, match in ((partial, "not a complete regime map"), (notes, "not a fricenv regime")):
        with pytest.raises(ValueError, match=match):
            RegimeMap.load(path)
        with pytest.raises(ValueError, match=match):
            regime_map(PARAMS, [1.0], [0.5], path=path, progress=False)
    assert notes.read_text() == "not an archive"  # and nothing was overwritten


def test_callback_is_checked_before_any_cell(tmp_path) -> None:
    with pytest.raises(TypeError, match=r"callback must be callable, got 5 \(int\)"):
        regime_map(PARAMS, [1.0], [0.5], callback=5, path=tmp_path / "m.npz")
    assert not any(tmp_path.iterdir())


# -- review 18: checks before the work, and nothing unwritten read as a result ---------------
def _count_cells(monkeypatch) -> list[int]:
    """Record the cells every run_cells call would run (regime_map's engine)."""
    from fricenv import cells

    ran: list[int] = []
    real = cells.run_cells

    def counting(P, *args, **kwargs):
        ran.append(len(P))
        return real(P, *args, **kwargs)

    monkeypatch.setattr(cells, "run_cells", counting)
    return ran


def test_run_cells_bounds_counts_before_the_int_cast() -> None:
    """n_segment = 1e20 was cast to INT_MIN, passed every check, and the cell came back as
    uninitialised memory, sometimes with status OK; tries = 1e20 ran as tries = 1."""
    from fricenv.layout import METHOD_EXACT
    from fricenv.sweep import MAX_LOCK_EXTENSIONS, MAX_SEGMENTS, run_cells

    P = np.stack([PARAMS.replace(u0=1.0, nu=0.5).to_array()] * 3)
    t = np.full(3, 5.0)
    with pytest.raises(ValueError, match=r"cell 1: n_segment must be at most 1000000, got 1e\+20"):
        run_cells(P, t, t, [1, 1e20, 1], [0, 0, 0], SweepSettings(), METHOD_EXACT)
    with pytest.raises(ValueError, match=rf"cell 0: tries must be at most "
                                         rf"{1 + MAX_LOCK_EXTENSIONS}, got 1e\+20"):
        run_cells(P, t, t, [1, 1, 1], [1e20, 0, 0], SweepSettings(), METHOD_EXACT)
    with pytest.raises(ValueError, match="n_segment must be at most"):
        run_cells(P, t, t, [1, MAX_SEGMENTS + 1, 1], [0, 0, 0], SweepSettings(), METHOD_EXACT)


@pytest.mark.parametrize("column, value, match", [
    (0, np.nan, r"P_cells\[1, 0\] \(lam\) must be finite and within \+-1e\+12 .*got nan"),
    (0, -5.0, r"P_cells\[1, 0\] \(lam\) must be >= 0, got -5\.0"),
    (2, 1e300, r"P_cells\[1, 2\] \(xfk\) must be finite and within"),
    (3, 1.0, r"P_cells\[1, 3\] \(xfs\) must be >= xfk, got 1\.0 \(xfk = 2\.5\)"),
    (4, -1.0, r"P_cells\[1, 4\] \(u1\) must be >= 0"),
    (6, 0.0, r"P_cells\[1, 6\] \(w1 = eta\) must be > 0"),
    (8, 7.0, r"P_cells\[1, 8\] \(law code\) must be a friction law's code"),
])
def test_run_cells_refuses_rows_that_oscillator_params_would(column: int, value: float,
                                                            match: str) -> None:
    """Rows were not checked: a NaN lam gave status 2, lam = -5, xfs < xfk or xfk = 1e300
    ran to numbers without a word."""
    from fricenv.layout import METHOD_EVENT
    from fricenv.sweep import run_cells

    P = np.stack([PARAMS.replace(u0=1.0, nu=0.5).to_array()] * 3)
    P[1, column] = value
    t = np.full(3, 5.0)
    with pytest.raises(ValueError, match=match):
        run_cells(P, t, t, np.ones(3), np.zeros(3), SweepSettings(), METHOD_EVENT)


def test_run_cells_checks_the_type_of_method_and_settings() -> None:
    from fricenv.sweep import run_cells

    P = PARAMS.replace(u0=1.0, nu=0.5).to_array()[None]
    one = ([5.0], [5.0], [1], [0])
    for method in (True, 0.0):  # were accepted as METHOD_EVENT / METHOD_EXACT
        with pytest.raises(TypeError, match=r"method must be an integer, got "):
            run_cells(P, *one, SweepSettings(), method)
    with pytest.raises(TypeError, match=r"settings must be a fricenv\.SweepSettings, got None"):
        run_cells(P, *one, None, 0)  # was AttributeError: no 'x0'


def test_run_cells_never_returns_a_cell_its_kernel_did_not_write(monkeypatch) -> None:
    """Outputs were np.empty: a cell the kernel skipped (an exception inside prange is lost)
    read as whatever the memory held. Now they start as NaN / STATUS_NOT_RUN, and any
    left so is an error."""
    from fricenv import cells, sweep
    from fricenv.layout import METHOD_EXACT

    monkeypatch.setitem(cells.CELL_KERNELS, METHOD_EXACT, lambda *args: None)  # writes nothing
    P = PARAMS.replace(u0=1.0, nu=0.5).to_array()[None]
    with pytest.raises(RuntimeError, match=r"left 1 cell\(s\) unrun"):
        sweep.run_cells(P, [5.0], [5.0], [1], [0], SweepSettings(), METHOD_EXACT)


@pytest.mark.parametrize("path, error, match", [
    (5, TypeError, r"path must be a str or os\.PathLike, got 5 \(int\)"),
    (b"x.npz", TypeError, r"path must be a str or os\.PathLike, got b'x\.npz' \(bytes\)"),
    ("", ValueError, r"path must name a file, got ''"),
])
def test_map_path_of_wrong_type_or_no_name(path: object, error: type, match: str,
                                          reference: RegimeMap) -> None:
    """These were TypeErrors from os / pathlib that named nothing ('' a ValueError about
    PosixPath('.'))."""
    with pytest.raises(error, match=match):
        regime_map(PARAMS, [1.0], [0.5], path=path, progress=False)
    with pytest.raises(error, match=match):
        reference.save(path)
    if error is TypeError:
        with pytest.raises(error, match=match):
            RegimeMap.load(path)


def test_unwritable_map_path_and_bad_meta_are_refused_before_any_cell(tmp_path,
                                                                      monkeypatch) -> None:
    """Each failed only at the first save, after a chunk of up to 2048 cells had run."""
    ran = _count_cells(monkeypatch)
    (tmp_path / "afile").touch()
    (tmp_path / "adir.npz").mkdir()
    cases = [
        (dict(path=tmp_path / "afile" / "m.npz"), ValueError, r"path .*afile.* is not a folder"),
        (dict(path=tmp_path / "adir.npz", resume=False), ValueError, r"adir\.npz' is a folder"),
        (dict(path=tmp_path / "adir"), ValueError, r"adir\.npz' is a folder"),  # .npz added
        # the check was json.dumps without the save's sort_keys: a non-str key passed it
        (dict(path=tmp_path / "m.npz", meta={1: "a"}), TypeError,
         "meta must hold JSON-able values under str keys"),
    ]
    for kwargs, error, match in cases:
        with pytest.raises(error, match=match):
            regime_map(PARAMS, [0.5, 1.0], [0.5], progress=False, **kwargs)
    assert ran == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir.npz", "afile"]
    m = regime_map(PARAMS, [0.5], [0.5], progress=False, meta={"note": 1})
    with pytest.raises(ValueError, match="is a folder"):
        m.save(tmp_path / "adir.npz")  # was IsADirectoryError from os.replace


def test_regime_map_refuses_tone_amplitudes_it_would_drop(monkeypatch) -> None:
    """params.u1 / u2 were silently replaced by the grid's u0 (and a file made with u1 = 3
    resumed as the same map)."""
    ran = _count_cells(monkeypatch)
    for kw in (dict(u1=3.0), dict(u2=0.0)):
        with pytest.raises(ValueError, match=r"params\.u1 / params\.u2 must be None"):
            regime_map(PARAMS.replace(**kw), [1.0], [0.5], progress=False)
    assert ran == []


@pytest.mark.parametrize("kwargs, match", [
    (dict(x0=1e13), r"x0 must lie within \+-1e\+12"),
    (dict(v0=1e200), r"v0 must lie within \+-1e\+12"),
    (dict(m_max=2**70), r"m_max must be an integer <= 1000, got 1180591620717411303424"),
    (dict(q_max=1001), r"q_max must be an integer <= 1000, got 1001"),
    (dict(lock_extensions=2**70), r"lock_extensions must be an integer <= 100, got"),
    (dict(n_strobe=2**70), r"n_strobe must be an integer <= 1000000, got"),
])
def test_sweep_settings_bounds(kwargs: dict, match: str, monkeypatch) -> None:
    """x0 = 1e300 / v0 = 1e200 ran (a WM2 label for a start at v0 = 1e200); huge counts gave
    a numba TypingError, an OverflowError or an int64 overflow blamed on n_segment."""
    ran = _count_cells(monkeypatch)
    with pytest.raises(ValueError, match=match):
        SweepSettings(**kwargs)
    with pytest.raises(ValueError, match=match):
        regime_map(PARAMS, [0.5], [1.0], progress=False, transient_min=5.0, window_min=5.0,
                   **kwargs)
    assert ran == []


def test_sweep_settings_maxima_are_accepted() -> None:
    from fricenv.sweep import MAX_LOCK_EXTENSIONS, MAX_PERIOD, MAX_SEGMENTS

    s = SweepSettings(q_max=MAX_PERIOD, m_max=MAX_PERIOD, lock_extensions=MAX_LOCK_EXTENSIONS,
                      n_strobe=MAX_SEGMENTS, x0=-1e12, v0=1e12)
    assert (s.q_max, s.n_strobe, s.v0) == (1000, 1_000_000, 1e12)


@pytest.mark.parametrize("kwargs, match", [
    (dict(window_min=1e300), r"nu = 0\.5: a window of 1e\+300 would keep 4\.775e\+298 "
                             r"stroboscopic samples .*the setting window_min = 1e\+300"),
    (dict(window_periods=1e10), r"would keep \d+ stroboscopic samples .*"
                                r"the setting window_periods = 10000000000\.0"),
])
def test_plan_names_the_setting_behind_too_many_segments(kwargs: dict, match: str) -> None:
    """The float segment count wrapped in the int64 cast (a RuntimeWarning, then an error
    about an internal n_segment of -9.2e18)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "invalid value encountered in cast"
        with pytest.raises(ValueError, match=match):
            plan_cells(PARAMS, np.array([0.5]), SweepSettings(**kwargs))
        with pytest.raises(ValueError, match=match):
            regime_map(PARAMS, [0.5], [0.5], progress=False, **kwargs)


def _rewrite(src, dst, **changes) -> None:
    """Copy the map file ``src`` to ``dst`` with some entries replaced (None: removed)."""
    with np.load(src) as z:
        entries = {k: z[k] for k in z.files}
    for k, v in changes.items():
        if v is None:
            entries.pop(k)
        else:
            entries[k] = v
    np.savez(dst, **entries)


def test_malformed_map_files_are_value_errors_naming_the_file(tmp_path, reference: RegimeMap,
                                                             monkeypatch) -> None:
    """Metadata of another shape gave AttributeError or KeyError; a labels array of the
    wrong shape loaded, and a resume from it failed mid-sweep with IndexError."""
    good = reference.save(tmp_path / "good.npz")
    with np.load(good) as z:
        meta = json.loads(str(z["meta"][()]))
    no_params = {k: v for k, v in meta.items() if k != "params"}
    bad_settings = {**meta, "settings": {**meta["settings"], "n_strobe": "12"}}
    cases = {
        "list": (dict(meta=np.array("[1]")), "its metadata is a list"),
        "noparams": (dict(meta=np.array(json.dumps(no_params))), "no 'params'"),
        "settings": (dict(meta=np.array(json.dumps(bad_settings))), "n_strobe must be"),
        "elapsed": (dict(meta=np.array(json.dumps({**meta, "elapsed_s": "x"}))), "elapsed_s"),
        "labels": (dict(labels=np.zeros((2, 2), np.int8)), r"labels must be of shape \(4, 5\)"),
        "stats": (dict(stats=np.zeros((4, 5, 3))), r"stats must be of shape \(4, 5, 11\)"),
        "done": (dict(done=np.zeros((4, 5), np.int8)), "done must be of shape"),
        "q": (dict(q=np.zeros(4, np.int16)), r"q must be of shape \(5,\)"),
        "plan": (dict(plan_tries=np.zeros(2, np.int64)), r"plan_tries must be of shape"),
        "nu": (dict(nu=np.array([0.5, np.nan, 1, 2, 3])), "nu grid contains NaN"),
        "object": (dict(u0=np.array([None, 1.0], dtype=object)), "unreadable"),
        # arrays of the right shapes that contradict each other (review 20: all loaded, and
        # a resume of the first one recomputed nothing and called the map complete)
        "unlabelled": (dict(labels=np.full((4, 5), NOT_COMPUTED, np.int8)),
                       "labels and done disagree"),
        "undone": (dict(done=np.zeros((4, 5), bool)), "labels and done disagree"),
        "regime": (dict(labels=np.full((4, 5), 42, np.int8)), "labels holds 42"),
        "wide": (dict(labels=np.zeros((4, 5), np.int64)), "labels must be int8, got int64"),
        "qplan": (dict(q=np.full(5, 3, np.int16)), r"q \[3, 3, 3, 3, 3\] differs from the plan"),
    }
    ran = _count_cells(monkeypatch)
    for name, (changes, match) in cases.items():
        path = tmp_path / f"{name}.npz"
        _rewrite(good, path, **changes)  # (np.savez pickles the object array)
        with pytest.raises(ValueError, match=rf"{name}\.npz.*{match}"):
            RegimeMap.load(path)
        with pytest.raises(ValueError, match=rf"{name}\.npz.*{match}"):  # before any cell
            regime_map(PARAMS, U0, NU, path=path, progress=False)
    assert ran == []
    _same(reference, RegimeMap.load(good))


def test_repeated_grid_values_are_named(tmp_path) -> None:
    with pytest.raises(ValueError, match=r"u0 grid must not repeat a value, got 5\.0 2 times"):
        regime_map(PARAMS, [1.0, 5.0, 5.0], [0.5], path=tmp_path / "m", progress=False)
    assert not list(tmp_path.iterdir())


def test_load_appends_npz_as_save_does(tmp_path, reference: RegimeMap) -> None:
    written = reference.save(tmp_path / "mymap")
    assert written.name == "mymap.npz"
    _same(reference, RegimeMap.load(tmp_path / "mymap"))
    _same(reference, RegimeMap.load(str(tmp_path / "mymap")))


def test_a_map_is_saved_every_few_seconds_not_after_every_chunk(tmp_path, reference,
                                                                monkeypatch) -> None:
    """A save rewrites the whole file: after every chunk, saving took 70 % on top of a 3 s
    map. Within SAVE_EVERY_S the map is saved once, at its end."""
    import fricenv.sweep as sweep

    saves: list[int] = []
    save = RegimeMap.save

    def counted(self: RegimeMap, path):
        saves.append(int(self.done.sum()))
        return save(self, path)

    monkeypatch.setattr(RegimeMap, "save", counted)
    path = tmp_path / "m.npz"
    regime_map(PARAMS, U0, NU, path=path, chunk_size=2, progress=False)
    assert saves == [20]
    _same(reference, RegimeMap.load(path))
    saves.clear()
    monkeypatch.setattr(sweep, "SAVE_EVERY_S", 0.0)
    regime_map(PARAMS, U0, NU, path=path, chunk_size=2, resume=False, progress=False)
    assert saves == list(range(2, 21, 2))
