"""Map files: a damaged one is a ValueError naming it, a second writer is refused, and a
grid too large for memory is refused before anything is allocated."""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import textwrap
import threading
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fricenv import mapfile
from fricenv.mapfile import MapInUseError
from fricenv.params import OscillatorParams
from fricenv.sweep import MAX_CELLS, RegimeMap, regime_map

PARAMS = OscillatorParams.preset("coulomb")
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def small_map() -> RegimeMap:
    return regime_map(PARAMS, [0.5, 3.0], [0.5, 1.3], progress=False)


def _same(a: RegimeMap, b: RegimeMap) -> None:
    for name in ("u0", "nu", "labels", "stats", "period", "status", "done", "q"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def header_positions(data: bytes) -> list[int]:
    """Every byte of the archive's structure: local file headers, each member's .npy
    header, the central directory and its end record (the data bytes are left out)."""
    pos: list[int] = []
    with zipfile.ZipFile(__import__("io").BytesIO(data)) as zf:
        infos = zf.infolist()
        cd_start = struct.unpack("<I", data[-6:-2])[0]
    for info in infos:
        o = info.header_offset
        n_name, n_extra = struct.unpack("<HH", data[o + 26:o + 30])
        start = o + 30 + n_name + n_extra  # the member's data: a .npy file
        hlen = struct.unpack("<H", data[start + 8:start + 10])[0]
        pos += range(o, start + 10 + hlen)
    pos += range(cd_start, len(data))
    return pos


def _expect_map_or_named_value_error(path: Path, original: RegimeMap) -> str:
    try:
        m = RegimeMap.load(path)
    except ValueError as e:
        assert str(path) in str(e), e
        return "error"
    _same(original, m)  # a change the archive does not read (a time stamp, a comment)
    return "same"


def test_an_empty_or_truncated_map_file_is_a_value_error_naming_it(tmp_path, small_map
                                                                   ) -> None:
    """An empty file gave EOFError from RegimeMap.load and regime_map(path=...)."""
    good = small_map.save(tmp_path / "good.npz").read_bytes()
    path = tmp_path / "m.npz"
    path.write_bytes(b"")
    with pytest.raises(ValueError, match=r"m\.npz is not a fricenv regime map") as info:
        RegimeMap.load(path)
    assert info.value.__cause__ is not None  # the parser's own error, chained
    with pytest.raises(ValueError, match=r"m\.npz is not a fricenv regime map"):
        regime_map(PARAMS, [0.5, 3.0], [0.5, 1.3], path=path, progress=False)
    assert path.read_bytes() == b""  # nothing overwritten
    for n in range(1, len(good), 97):
        path.write_bytes(good[:n])
        with pytest.raises(ValueError, match=r"m\.npz is not a fricenv regime map"):
            RegimeMap.load(path)


def test_each_changed_header_byte_gives_the_map_or_a_value_error(tmp_path, small_map) -> None:
    """Single-byte changes of the zip and .npy headers raised BadZipFile,
    NotImplementedError, tokenize.TokenError or OSError (127 of 2,081 positions)."""
    good = small_map.save(tmp_path / "good.npz").read_bytes()
    path = tmp_path / "m.npz"
    seen = {"error": 0, "same": 0}
    rng = np.random.default_rng(0)
    positions = header_positions(good)  # 3,720: 1,500 of them (all in the slow test below)
    for k in sorted(rng.choice(positions, 1500, replace=False)):
        data = bytearray(good)
        data[k] = (data[k] + int(rng.integers(1, 256))) % 256
        path.write_bytes(bytes(data))
        seen[_expect_map_or_named_value_error(path, small_map)] += 1
    assert seen["error"] > 500


@pytest.mark.slow
def test_every_changed_byte_gives_the_map_or_a_value_error(tmp_path, small_map) -> None:
    good = small_map.save(tmp_path / "good.npz").read_bytes()
    path = tmp_path / "m.npz"
    for k in range(len(good)):
        for value in (0x00, 0xFF, good[k] ^ 0x01, good[k] ^ 0x80):
            if value == good[k]:
                continue
            data = bytearray(good)
            data[k] = value
            path.write_bytes(bytes(data))
            _expect_map_or_named_value_error(path, small_map)


def _rewritten(good: Path, path: Path, names: tuple[str, ...], change) -> Path:
    """``good`` with the arrays ``names`` changed by ``change(array)`` (in place), written
    as a well-formed archive with valid checksums."""
    with np.load(good) as z:
        entries = {k: z[k] for k in z.files}
    for name in names:
        change(entries[name])
    np.savez(path, **entries)
    return path


def test_well_formed_maps_with_impossible_contents_are_refused(tmp_path, small_map) -> None:
    """A map rewritten with valid checksums and inf or all-NaN statistics, a period of -3
    or a status of 77 loaded, and a resume kept it; now each is the named ValueError of a
    damaged file, naming the array and the first bad cell."""
    from fricenv.layout import STATUS_OK

    good = small_map.save(tmp_path / "good.npz")
    ok = np.argwhere(small_map.done & (small_map.status == STATUS_OK))
    assert len(ok) > 0
    i, j = (int(k) for k in ok[-1])
    u0, nu = float(small_map.u0[i]), float(small_map.nu[j])
    where = rf"cell \({i}, {j}\) \(u0 = {u0!r}, nu = {nu!r}\)"

    def put(value, at=(i, j)):
        def change(a):
            a[at] = value
        return change

    cases = {
        "inf": (("stats",), put(np.inf, (i, j, 1)),
                rf"stats holds inf at {where}, statistic 'stick_time': .*finite"),
        "nan": (("stats",), put(np.nan), rf"stats holds nan at {where}, statistic 'duration'"),
        "vr2": (("stats",), put(-np.inf, (i, j, 9)), rf"stats holds -inf at {where}, "
                                                     "statistic 'vr2_int'"),
        "period": (("period",), put(-3), rf"period holds -3 at {where}: period is >= 0"),
        "status": (("status",), put(77),
                   rf"status holds 77 at {where}: a status is one of \[0, 1, 2"),
        "q": (("q", "plan_q"), put(-2, (j,)), rf"q holds -2 at nu\[{j}\] = {nu!r}"),
        "label": (("labels",), put(9), r"labels holds 9, neither a Regime value"),
    }
    for case, (names, change, match) in cases.items():
        path = _rewritten(good, tmp_path / f"{case}.npz", names, change)
        with pytest.raises(ValueError, match=rf"{case}\.npz is not a fricenv regime map \("
                                             + match):
            RegimeMap.load(path)
        with pytest.raises(ValueError, match=rf"{case}\.npz is not a fricenv regime map"):
            regime_map(PARAMS, small_map.u0, small_map.nu, path=path, progress=False)
    _same(small_map, RegimeMap.load(good))


def test_archives_claiming_huge_arrays_are_refused_before_allocating(tmp_path) -> None:
    path = tmp_path / "m.npz"
    with zipfile.ZipFile(path, "w") as zf:  # a .npy header asking for 8e15 bytes
        zf.writestr("meta.npy", b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', 'fortran_order': "
                    b"False, 'shape': (1000000000000000,), }" + b" " * 60 + b"\n")
    with pytest.raises(ValueError, match="declares 8000000000000000 bytes"):
        RegimeMap.load(path)


def test_a_missing_path_keeps_its_os_error(tmp_path) -> None:
    with pytest.raises(FileNotFoundError):
        RegimeMap.load(tmp_path / "none.npz")
    (tmp_path / "folder.npz").mkdir()
    with pytest.raises(IsADirectoryError):
        RegimeMap.load(tmp_path / "folder.npz")


# -- one writer at a time -----------------------------------------------------------------
_WRITER = textwrap.dedent("""
    import sys
    import fricenv

    def wait(rmap, n):  # holds the sweep, and so its lock, until stdin closes
        print("running", flush=True)
        sys.stdin.read()

    fricenv.regime_map("coulomb", [0.5], [0.5, 1.3], path=sys.argv[1], chunk_size=1,
                       callback=wait, progress=False)
""")


def _start_writer(path: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", _WRITER, str(path)], env=env,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline() == "running\n"
    return proc


def test_a_second_writer_is_refused_while_the_first_holds_the_map(tmp_path) -> None:
    """Both writers exited 0 and the last one silently won."""
    path = tmp_path / "m.npz"
    proc = _start_writer(path)
    try:
        with pytest.raises(MapInUseError, match=r"m\.npz is being written by another sweep "
                                                rf"\(process {proc.pid} on "):
            regime_map(PARAMS, [2.0], [0.5], path=path, progress=False)
        with pytest.raises(MapInUseError):
            regime_map("coulomb", [0.5], [0.5, 1.3], path=path, progress=False)
    finally:
        proc.communicate("", timeout=600)  # let the first writer finish
    assert proc.returncode == 0
    m = RegimeMap.load(path)
    assert m.complete and list(m.u0) == [0.5]  # the first writer's map
    assert not mapfile.lock_path(path).exists()
    regime_map(PARAMS, [2.0], [0.5], path=path, resume=False, progress=False)  # free again


def test_a_killed_writer_leaves_no_stale_lock(tmp_path) -> None:
    path = tmp_path / "m.npz"
    proc = _start_writer(path)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    proc.stdin.close()
    proc.stdout.close()
    assert mapfile.lock_path(path).exists()  # left behind, but no longer held
    m = regime_map("coulomb", [0.5], [0.5, 1.3], path=path, progress=False)
    assert m.complete and not mapfile.lock_path(path).exists()


def test_a_save_from_another_thread_is_refused_during_a_sweep(tmp_path, small_map) -> None:
    path = tmp_path / "m.npz"
    errors: list[BaseException] = []

    def save_elsewhere(rmap: RegimeMap, n: int) -> None:
        def other() -> None:
            try:
                small_map.save(path)
            except MapInUseError as e:
                errors.append(e)
        t = threading.Thread(target=other)
        t.start()
        t.join()
        small_map.save(tmp_path / "other.npz")  # another map: no conflict

    regime_map(PARAMS, [0.5], [0.5], path=path, callback=save_elsewhere, progress=False)
    assert len(errors) == 1 and "being written by another sweep" in str(errors[0])
    small_map.save(path)  # after the sweep: free


def test_a_grid_too_large_for_memory_is_refused_before_anything_is_allocated(tmp_path
                                                                             ) -> None:
    u0 = np.linspace(0.0, 1.0, 20_000)
    nu = np.linspace(0.0, 2.0, MAX_CELLS // 20_000 + 1)
    with pytest.raises(ValueError, match=rf"has {u0.size * nu.size} cells, more than "
                                         rf"MAX_CELLS = {MAX_CELLS}"):
        regime_map(PARAMS, u0, nu, path=tmp_path / "m.npz", progress=False)
    assert not list(tmp_path.iterdir())


def test_a_map_named_with_another_suffix_is_read_as_named(tmp_path, small_map) -> None:
    """RegimeMap.load('x.npy') on an existing x.npy said FileNotFoundError for x.npy.npz."""
    npy = tmp_path / "x.npy"
    np.save(npy, np.zeros(3))
    with pytest.raises(ValueError, match=r"x\.npy is not a fricenv regime map"):
        RegimeMap.load(npy)
    kept = tmp_path / "m.map"
    kept.write_bytes(small_map.save(tmp_path / "m.npz").read_bytes())
    _same(small_map, RegimeMap.load(kept))
    small_map.save(tmp_path / "both.map")  # both.map.npz: the name save gives it wins
    (tmp_path / "both.map").write_bytes(b"not a map")
    _same(small_map, RegimeMap.load(tmp_path / "both.map"))


def test_labels_that_contradict_the_statistics_are_refused(tmp_path, small_map) -> None:
    """A well-formed map whose label says another regime than its own statistics loaded,
    and a resume kept the label."""
    from fricenv.regimes import Regime

    good = small_map.save(tmp_path / "good.npz")
    i, j = (int(k) for k in np.argwhere(small_map.done)[-1])
    was = Regime(int(small_map.labels[i, j]))
    other = Regime.WM2 if was != Regime.WM2 else Regime.SSM1

    def relabel(a):
        a[i, j] = int(other)

    path = _rewritten(good, tmp_path / "relabelled.npz", ("labels",), relabel)
    match = (rf"relabelled\.npz is not a fricenv regime map \(labels holds {other.name} at "
             rf"cell \({i}, {j}\) .* statistics give {was.name} \(1 cells disagree\)")
    with pytest.raises(ValueError, match=match):
        RegimeMap.load(path)
    with pytest.raises(ValueError, match=match):
        regime_map(PARAMS, small_map.u0, small_map.nu, path=path, progress=False)
    _same(small_map, RegimeMap.load(good))


def test_a_symlinked_map_keeps_its_link_and_shares_its_targets_lock(tmp_path,
                                                                    small_map) -> None:
    """The lock was taken on the path as given, so a writer through a symlink ran beside
    one through the target; a save replaced the symlink with a regular file."""
    (tmp_path / "data").mkdir()
    target = tmp_path / "data" / "m.npz"
    link = tmp_path / "link.npz"
    link.symlink_to(target)
    small_map.save(link)
    assert link.is_symlink() and os.readlink(link) == str(target) and target.is_file()
    regime_map(PARAMS, [0.5, 3.0, 9.0], [0.5, 1.3], path=link, resume=False, progress=False)
    assert link.is_symlink() and RegimeMap.load(target).shape == (3, 2)
    assert not list(tmp_path.glob("link.npz.*")) and not list(target.parent.glob("*.tmp*"))
    held, release = threading.Event(), threading.Event()

    def hold() -> None:
        with mapfile.writer_lock(target):
            held.set()
            release.wait(60)

    t = threading.Thread(target=hold)
    t.start()
    try:
        assert held.wait(60)
        with pytest.raises(MapInUseError, match=r"m\.npz is being written"):
            small_map.save(link)
        with pytest.raises(MapInUseError):
            regime_map(PARAMS, [0.5], [0.5], path=link, resume=False, progress=False)
    finally:
        release.set()
        t.join()
    small_map.save(link)  # free again
    assert link.is_symlink()
