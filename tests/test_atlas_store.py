"""Atlas stores cannot rot silently: every chunk and metadata document carries a checksum,
damage is refused by name or computed again on resume, one writer at a time; and an
atlas's up-front checks are bounded (a cell limit, vectorised plans)."""

from __future__ import annotations

import fractions
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

import fricenv
from fricenv import regimes
from fricenv.atlas import core, store
from fricenv.mapfile import MapInUseError

ROOT = Path(__file__).resolve().parents[1]
AXES = {"u0": np.geomspace(0.2, 40.0, 4), "nu": np.array([0.25, 0.5, 1.0, 1.3, 2.0])}
CHUNKS = (2, 2)  # 6 chunks of at most 4 cells
N_CHUNKS = 6


def _run(path: Path | None = None, axes: dict | None = None) -> xr.Dataset:
    return fricenv.atlas("coulomb", AXES if axes is None else axes, path=path,
                         chunks=CHUNKS, progress=False)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> tuple[xr.Dataset, Path]:
    """The uninterrupted atlas in memory, and a pristine store of it (copy before use)."""
    path = tmp_path_factory.mktemp("ref") / "ref.zarr"
    _run(path)
    return _run(), path


@pytest.fixture
def fresh(reference, tmp_path) -> Path:
    path = tmp_path / "a.zarr"
    shutil.copytree(reference[1], path)
    return path


def _flip(file: Path, bit: int) -> None:
    data = bytearray(file.read_bytes())
    data[bit // 8] ^= 1 << (bit % 8)
    file.write_bytes(bytes(data))


def _counting_compute(monkeypatch) -> list:
    ran: list = []
    original = core.compute_chunk
    monkeypatch.setattr(core, "compute_chunk",
                        lambda task, n=None: ran.append(task.index) or original(task, n))
    return ran


def _chunk_files(path: Path, name: str) -> list[tuple[tuple[int, ...], Path]]:
    files = sorted(f for f in (path / name / "c").rglob("*") if f.is_file())
    return [(tuple(int(p) for p in f.relative_to(path / name / "c").parts), f)
            for f in files]


def test_every_chunk_file_is_written_and_checksummed(fresh):
    for name in core.VARIABLES:  # fill-valued chunks too (period is 0 in most cells)
        assert len(_chunk_files(fresh, name)) == N_CHUNKS, name
        codecs = json.loads((fresh / name / "zarr.json").read_text())["codecs"]
        assert [c["name"] for c in codecs][-1] == "crc32c"
    ds = xr.open_zarr(fresh, consolidated=False)  # plain xarray reads it
    assert ds.label.dims == ("u0", "nu")


@pytest.mark.parametrize("name", [*core.VARIABLES, "u0", "nu", "q"])
def test_bit_flips_in_chunk_files_are_refused_by_name(fresh, name):
    """A deterministic sample: every chunk file of the array, a bit at its start, inside
    and in its checksum. None loads as a value."""
    for index, file in _chunk_files(fresh, name):
        size = 8 * file.stat().st_size
        for bit in (3, size // 2 + 1, size - 5):
            _flip(file, bit)
            with pytest.raises(ValueError, match=rf"{re.escape(str(fresh))}.*{name!r}") as err:
                fricenv.open_atlas(fresh)
            if name in core.VARIABLES:
                assert f"chunk {index}" in str(err.value)
            _flip(file, bit)
    fricenv.open_atlas(fresh)  # (flipped back: intact again)


def test_a_flip_after_opening_never_reads_as_a_value(fresh, reference):
    ds = fricenv.open_atlas(fresh)
    _flip(fresh / "v_max" / "c" / "1" / "1", 40)
    with pytest.raises(Exception, match="checksum"):
        ds.v_max.load()
    np.testing.assert_array_equal(ds.label.values, reference[0].label.values)


def test_resume_recomputes_damaged_chunks_bit_for_bit(fresh, reference, monkeypatch):
    _flip(fresh / "n_stick" / "c" / "1" / "0", 50)
    _flip(fresh / "label" / "c" / "0" / "2", 7)
    ran = _counting_compute(monkeypatch)
    with pytest.warns(UserWarning, match=r"2 damaged chunks are computed again"):
        ds = _run(fresh)
    assert sorted(ran) == [(0, 2), (1, 0)]
    xr.testing.assert_identical(ds.load(), reference[0])


def test_deleted_chunk_file_is_refused_then_recomputed(fresh, reference, monkeypatch):
    (fresh / "stick_fraction" / "c" / "0" / "1").unlink()
    with pytest.raises(ValueError, match=r"chunk \(0, 1\) of variable 'stick_fraction'.* "
                                         "is missing"):
        fricenv.open_atlas(fresh)
    ran = _counting_compute(monkeypatch)
    with pytest.warns(UserWarning, match="damaged"):
        ds = _run(fresh)
    assert ran == [(0, 1)]
    xr.testing.assert_identical(ds.load(), reference[0])
    ran.clear()
    _run(fresh)
    assert ran == []


def test_chunks_cut_off_by_a_kill_read_as_not_computed(fresh, monkeypatch):
    """Label written last: a chunk without its label was in flight, not damaged."""
    for name in ("label", "status", "period"):
        (fresh / name / "c" / "1" / "2").unlink()
    ds = fricenv.open_atlas(fresh)
    assert (ds.label.values == -1).sum() == 2
    ran = _counting_compute(monkeypatch)
    _run(fresh)
    assert ran == [(1, 2)]


def _swap(a: Path, b: Path) -> None:
    data = a.read_bytes()
    a.write_bytes(b.read_bytes())
    b.write_bytes(data)


def test_chunk_files_out_of_place_are_refused_then_recomputed(fresh, reference, tmp_path,
                                                               monkeypatch):
    """Chunk files swapped between positions or variables, or copied from another atlas of
    the same shape, matched their own checksums and loaded as this atlas's cells."""
    other = tmp_path / "other.zarr"
    fricenv.atlas("coulomb", {"u0": AXES["u0"] * 1.5, "nu": AXES["nu"]}, path=other,
                  chunks=CHUNKS, progress=False)
    cases = [  # (files to swap or copy, the chunks that must be computed again)
        ("swap", fresh / "label" / "c" / "0" / "0", fresh / "label" / "c" / "1" / "1"),
        ("swap", fresh / "v_min" / "c" / "0" / "1", fresh / "v_max" / "c" / "0" / "1"),
        ("copy", other / "label" / "c" / "1" / "0", fresh / "label" / "c" / "1" / "0"),
        ("copy", other / "label" / "records" / "1.0.json",  # a record from elsewhere too
         fresh / "label" / "records" / "1.0.json"),
    ]
    before = {f: f.read_bytes() for f in fresh.rglob("*") if f.is_file()}
    for kind, a, b in cases:
        _swap(a, b) if kind == "swap" else shutil.copy(a, b)
    changed = {f for f in before if f.read_bytes() != before[f]}
    # (the chunks the damage touched: a record is named i.j.json, a chunk file .../c/i/j)
    expected = sorted({tuple(int(x) for x in f.name.split(".")[:2]) if f.suffix == ".json"
                       else (int(f.parent.name), int(f.name)) for f in changed})
    assert len(expected) >= 3  # (the swaps and copies change bytes: the test tests)
    assert not np.array_equal(
        xr.open_zarr(fresh, consolidated=False).label.values, reference[0].label.values)
    with pytest.raises(ValueError, match=r"chunk \(\d, \d\) of variable '\w+' .* is not the "
                                         r"file written there .*more damaged chunk files"):
        fricenv.open_atlas(fresh)
    ran = _counting_compute(monkeypatch)
    with pytest.warns(UserWarning, match=rf"{len(expected)} damaged chunks are computed again"):
        ds = _run(fresh)
    assert sorted(ran) == expected
    xr.testing.assert_identical(ds.load(), reference[0])


def test_a_chunk_without_its_record_is_refused_then_recomputed(fresh, reference, monkeypatch):
    (fresh / "label" / "records" / "1.2.json").unlink()  # (a kill before the record)
    with pytest.raises(ValueError, match=r"chunk \(1, 2\) .* is not the file written"):
        fricenv.open_atlas(fresh)
    ran = _counting_compute(monkeypatch)
    with pytest.warns(UserWarning, match="1 damaged chunks"):
        ds = _run(fresh)
    assert ran == [(1, 2)]
    xr.testing.assert_identical(ds.load(), reference[0])


def _set_json(file: Path, edit) -> None:
    meta = json.loads(file.read_text())
    edit(meta)
    file.write_text(json.dumps(meta))


@pytest.mark.parametrize("name", ["", "u0", "q", "label", "v_min"])
@pytest.mark.parametrize("damage", ["garbage", "truncated", "valid json"])
def test_damaged_metadata_is_refused_by_name(fresh, name, damage):
    file = fresh / name / "zarr.json"
    if damage == "garbage":
        file.write_bytes(b"\x00\xff{")
    elif damage == "truncated":
        file.write_bytes(file.read_bytes()[:40])
    elif name:  # a shape that still parses: "cannot reshape" before
        _set_json(file, lambda m: m.update(shape=[n + 1 for n in m["shape"]]))
    else:
        _set_json(file, lambda m: m["attributes"].update(base=m["attributes"]["base"]
                                                         .replace("0.5", "0.7")))
    what = f"array {name!r}" if name else "group's metadata"
    for call in (lambda: fricenv.open_atlas(fresh), lambda: _run(fresh)):
        with pytest.raises(ValueError, match=rf"{re.escape(str(fresh))} is a damaged atlas store: "
                                             rf"(the metadata of )?(the )?{what}") as err:
            call()
        if damage != "valid json":
            assert err.value.__cause__ is not None


@pytest.mark.parametrize(("version", "why"), [
    (1, "whose chunks carry no checksums"),
    (2, "whose chunks are not bound to their place"),
    (3, "without the lyapunov variable"),
])
def test_store_of_an_older_format_is_refused(fresh, version, why):
    _set_json(fresh / "zarr.json", lambda m: m["attributes"].update(format_version=version))
    for call in (lambda: fricenv.open_atlas(fresh), lambda: _run(fresh)):
        with pytest.raises(ValueError, match=f"format version {version}, {why}.*remove it"):
            call()


def test_coordinate_mismatch_names_the_first_differing_value(fresh):
    u0 = AXES["u0"].copy()
    u0[2] = np.nextafter(u0[2], 1.0)
    want = (f"its u0 grid differs: first at index 2, stored {float(AXES['u0'][2])!r}, "
            f"given {float(u0[2])!r} (1 of 4 values differ)")
    with pytest.raises(ValueError, match=re.escape(want)):
        _run(fresh, {"u0": u0, "nu": AXES["nu"]})


def test_second_writer_refused_readers_not(fresh, reference):
    code = ("import sys; from pathlib import Path; from fricenv.mapfile import writer_lock\n"
            "with writer_lock(Path(sys.argv[1])):\n"
            "    print('held', flush=True); sys.stdin.read()\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    holder = subprocess.Popen([sys.executable, "-c", code, str(fresh)], cwd=ROOT, env=env,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        assert (fresh.parent / "a.zarr.lock").exists()
        with pytest.raises(MapInUseError, match=rf"{re.escape(str(fresh))} is being written"):
            _run(fresh)
        xr.testing.assert_identical(fricenv.open_atlas(fresh).load(), reference[0])
    finally:
        holder.communicate("")
    _run(fresh)  # released with its process
    assert not (fresh.parent / "a.zarr.lock").exists()


def test_huge_axes_refused_before_any_work_per_value(monkeypatch):
    def no_plans(*args, **kw):
        raise AssertionError("planned cells of an atlas over the cell limit")

    monkeypatch.setattr(core, "plan_cells", no_plans)
    axes = {k: np.linspace(0.1, 3.0, 10**4) for k in ("u0", "nu", "eta")}
    t = time.perf_counter()
    with pytest.raises(ValueError, match=r"\(10000, 10000, 10000\) has 1e\+12 cells, more "
                                         r"than MAX_CELLS = 1e\+10"):
        fricenv.atlas("coulomb", axes, progress=False)
    assert time.perf_counter() - t < 5.0


def test_huge_axes_refused_from_their_lengths_before_their_values():
    """The cell limit is checked from the axes' lengths before any value is looked at: a
    grid of 10^11 cells whose u0 axis repeats a value (a check that sorts every axis, 1-3 s
    for two axes of 10^7 values) is refused for its size."""
    axes = {"u0": np.zeros(10**5), "nu": np.linspace(0.1, 3.0, 10**3),
            "eta": np.linspace(0.2, 2.0, 10**3)}
    with pytest.raises(ValueError, match=r"\(100000, 1000, 1000\) has 1e\+11 cells, more "
                                         r"than MAX_CELLS = 1e\+10"):
        core.make_spec("coulomb", axes, None, None, 2)


def test_large_axis_plans_without_a_fraction_per_value(monkeypatch):
    nu = np.linspace(0.013, 4.0, 10**5)
    core.make_spec("coulomb", {"nu": nu[:10], "u0": [1.0]}, None, None, 2)  # (warm up)
    calls = []
    real = fractions.Fraction
    monkeypatch.setattr(regimes, "Fraction", lambda x: calls.append(x) or real(x))
    t = time.perf_counter()
    spec = core.make_spec("coulomb", {"nu": nu, "u0": [1.0]}, None, None, 2)
    assert time.perf_counter() - t < 10.0
    assert len(calls) < 100, len(calls)  # (one per value: 300,000 over three plans)
    q = store._q(spec)[1]
    monkeypatch.undo()
    want = [regimes.rational_denominator(float(x), spec.settings.q_max) for x in nu]
    np.testing.assert_array_equal(q, want)


_NU = st.one_of(
    st.floats(0.0, 1e6, allow_nan=False),
    st.builds(lambda p, q, e: p / q * (1.0 + e), st.integers(0, 10**6), st.integers(1, 12),
              st.sampled_from([0.0, 1e-16, -1e-16, 5e-10, -5e-10, 1e-9, -1e-9, 2e-9, 3e-9])),
    st.sampled_from([0.0, 5e-324, 1e300, 1.7976931348623157e308]))


@settings(max_examples=300, deadline=None)
@given(st.lists(_NU, max_size=30), st.integers(-1, 80),
       st.sampled_from([0.0, 1e-12, 1e-9, 1e-6, 0.01, 0.4]))
def test_vectorised_rationals_equal_the_scalar_functions(nu, q_max, tol):
    arr = np.array(nu, dtype=float)
    q = regimes.rational_denominators(arr, q_max, tol)
    assert q.tolist() == [regimes.rational_denominator(x, q_max, tol) for x in nu]
    ok = [k for k, (x, d) in enumerate(zip(nu, q.tolist(), strict=True))
          if d == 0 or abs(x * d) < 1e308]
    exact = regimes.exact_rationals(arr[ok], q[ok])
    assert exact.tolist() == [regimes.exact_rational(nu[k], int(q[k])) for k in ok]
