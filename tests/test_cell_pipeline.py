"""One path from parameters to labels: an atlas (local), ``regime_map`` and
``cell_statistics`` measure the same cell to the same bits, labels and every stored
variable, for any settings (initial state included), also where the block stays stuck all
window long."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import fricenv
from fricenv.atlas import regime_map_dataset
from fricenv.cells import CELL_FIELDS, NOT_COMPUTED, measure_cells
from fricenv.layout import ST_N_REVERSAL, ST_N_SLIP, ST_N_STICK, ST_STICK_TIME, STATUS_OK
from fricenv.params import OscillatorParams
from fricenv.regimes import Regime
from fricenv.sweep import SweepSettings, cell_statistics, regime_map

#: Short cells (tens of time units) that still test integer nu for periodicity.
SHORT = dict(transient_min=8.0, window_min=8.0, transient_periods=0.0, window_periods=0.0,
             transient_efolds=0.0, q_max=1, m_max=2, n_strobe=5, lock_extensions=0)
#: A block on a belt at rest, |forcing| <= 2 u0 below the static level 4: held from rest.
HELD = OscillatorParams(V=0.0)


def _three_ways(base: OscillatorParams, u0: list[float], nu: list[float],
                settings_: SweepSettings) -> tuple[xr.Dataset, fricenv.RegimeMap, tuple]:
    """The cells of the ``u0 x nu`` grid by an atlas, a regime map and cell_statistics."""
    ds = fricenv.atlas(base, {"u0": u0, "nu": nu}, settings=settings_, chunks=2,
                       progress=False)
    rmap = regime_map(base, u0, nu, settings=settings_, progress=False)
    cells = cell_statistics([base.replace(u0=a, nu=b) for a in u0 for b in nu], settings_)
    return ds, rmap, cells


def _assert_same_bits(ds: xr.Dataset, rmap: fricenv.RegimeMap, cells: tuple) -> None:
    xr.testing.assert_identical(ds, regime_map_dataset(rmap))  # labels and every stored variable
    labels, stats, period, status = cells
    shape = rmap.shape
    np.testing.assert_array_equal(labels.reshape(shape), rmap.labels)
    np.testing.assert_array_equal(stats.reshape(rmap.stats.shape), rmap.stats)  # (NaN = NaN)
    np.testing.assert_array_equal(period.reshape(shape), rmap.period)
    np.testing.assert_array_equal(status.reshape(shape), rmap.status)
    assert np.all(rmap.done) and not np.any(rmap.labels == NOT_COMPUTED)


def test_a_block_stuck_all_window_long_is_stuck_every_way():
    """The atlas once labelled it without the stick -> slip count: SSM1 / SSM2 where the
    regime map and cell_statistics said STUCK."""
    u0, nu = [0.0, 1.0], [0.5, 2.0]
    ds, rmap, cells = _three_ways(HELD, u0, nu, SweepSettings(**SHORT))
    assert np.all(rmap.labels == Regime.STUCK), rmap.labels
    assert np.all(rmap.stats[..., [ST_N_STICK, ST_N_SLIP, ST_N_REVERSAL]] == 0)
    _assert_same_bits(ds, rmap, cells)


def test_a_cell_in_a_list_of_other_laws_is_measured_as_alone():
    """cell_statistics ran every entry of a list holding a non-Coulomb one by the event
    method, so a Coulomb cell's bits depended on its neighbours and differed from the
    map's, which runs it in closed form."""
    coulomb = OscillatorParams(u0=2.0, nu=0.5)
    mixed = cell_statistics([coulomb, OscillatorParams.preset("stribeck", u0=2.0)], **SHORT)
    alone = cell_statistics([coulomb], **SHORT)
    rmap = regime_map(coulomb, [2.0], [0.5], progress=False, **SHORT)
    for a, b in zip(mixed, alone, strict=True):
        np.testing.assert_array_equal(a[:1], b)
    np.testing.assert_array_equal(alone[1][0], rmap.stats[0, 0])
    assert alone[0][0] == rmap.labels[0, 0]


@st.composite
def cases(draw) -> tuple[OscillatorParams, list[float], list[float], SweepSettings]:
    law = draw(st.sampled_from(["coulomb", "viscous", "stribeck"]))
    base = OscillatorParams.preset(law, V=draw(st.sampled_from([0.0, 0.5, 1.0])),
                                   eta=draw(st.sampled_from([0.6, 1.0, 1.7])),
                                   lam=draw(st.sampled_from([0.3, 0.5])))
    amplitude = st.one_of(st.sampled_from([0.0, 0.4, 1.0, 2.0, 6.0]),
                          st.floats(0.0, 8.0, allow_subnormal=False))
    ratio = st.one_of(st.sampled_from([0.25, 0.5, 0.7071, 1.0, 1.3, 2.0]),
                      st.floats(0.05, 3.0, allow_subnormal=False))
    u0 = draw(st.lists(amplitude, min_size=1, max_size=3, unique=True))
    nu = draw(st.lists(ratio, min_size=1, max_size=3, unique=True))
    state = st.floats(-3.0, 3.0, allow_nan=False, allow_subnormal=False)
    settings_ = SweepSettings(**{
        **SHORT, "x0": draw(state), "v0": draw(state),
        "transient_min": draw(st.sampled_from([0.0, 5.0, 20.0])),
        "window_min": draw(st.sampled_from([3.0, 10.0])),
        "q_max": draw(st.integers(0, 2)), "lock_extensions": draw(st.integers(0, 2)),
        "method": draw(st.sampled_from(["auto", "event"]))})
    return base, u0, nu, settings_


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(cases())
@example((HELD, [0.0, 1.0], [0.5, 1.0], SweepSettings(**{**SHORT, "x0": 1.5, "v0": -0.5})))
def test_atlas_regime_map_and_cell_statistics_agree_bit_for_bit(case) -> None:
    base, u0, nu, settings_ = case
    ds, rmap, cells = _three_ways(base, u0, nu, settings_)
    _assert_same_bits(ds, rmap, cells)
    stuck = ((rmap.status == STATUS_OK) & (rmap.stats[..., ST_STICK_TIME] > 0)
             & np.all(rmap.stats[..., [ST_N_STICK, ST_N_SLIP, ST_N_REVERSAL]] == 0, axis=-1))
    assert np.all(rmap.labels[stuck] == Regime.STUCK)


def test_measure_cells_refuses_bad_values():
    s = SweepSettings(**SHORT)
    with pytest.raises(ValueError, match=r"'x0' is not a field a cell can set"):
        measure_cells(HELD, {"x0": [1.0]}, s)
    with pytest.raises(ValueError, match="one length"):
        measure_cells(HELD, {"u0": [1.0, 2.0], "nu": [0.5]}, s)
    with pytest.raises(ValueError, match="values is empty"):
        measure_cells(HELD, {}, s)
    with pytest.raises(ValueError, match=r"values\['u0'\] must be 1-d"):
        measure_cells(HELD, {"u0": [[1.0]]}, s)
    with pytest.raises(TypeError, match="values must be a mapping"):
        measure_cells(HELD, [1.0], s)  # type: ignore[arg-type]
    assert set(CELL_FIELDS) == {"u0", "u1", "u2", "nu", "eta", "lam", "V", "xfk", "xfs",
                                "b1", "b3", "vs", "delta", "cv"}
