"""Regime-map files: reading an archive that may be damaged, and one writer at a time.

Reading. ``numpy.load`` trusts the archive: a damaged one fails with whatever its parsers
meet first (``EOFError`` for an empty file, ``BadZipFile``, ``NotImplementedError``,
``tokenize.TokenError``, ``OSError``...), and a size field changed by one byte can ask
for terabytes. :func:`read_npz` checks each member's zip entry and ``.npy`` header
against the bytes actually there before it allocates anything, reads the data through the
zip's CRC check, and turns any failure into ``ValueError: <file> is not a fricenv regime
map (<cause>)`` with the cause chained. A path that cannot be opened (missing, a folder,
no permission) keeps its own ``OSError``: it is a path to fix, not a file to distrust.

Writing. A sweep holds an exclusive lock on ``<map>.lock`` (beside the map's resolved
path, so symlinks to one map share its lock) while it runs, and
:meth:`RegimeMap.save` takes it for the moment of its write, so a second sweep (or a save
from another process) on the same map is refused with :class:`MapInUseError` instead of
silently overwriting the first one's work. The lock is the operating system's
(``flock``, or ``msvcrt.locking`` on Windows): it dies with the process that holds it, so
a crash or a kill never leaves a map locked; the lock file is removed on release.
"""

from __future__ import annotations

import contextlib
import os
import socket
import threading
import zipfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None  # type: ignore[assignment]
    import msvcrt

#: Most bytes a member may inflate to per compressed byte: deflate's own limit is 1032.
#: A larger claim is damage (and would have the reader allocate for it).
MAX_INFLATION = 1100
#: Suffix of the lock file next to a map: ``m.npz`` is locked through ``m.npz.lock``.
LOCK_SUFFIX = ".lock"


class MapInUseError(RuntimeError):
    """Another sweep or save holds the map's writer lock."""


class _Damage(ValueError):
    """What :func:`read_npz` found wrong with an archive (its message is the cause)."""


def not_a_map(path: Path, why: str) -> ValueError:
    """The error for a file that is no regime map (raise it ``from`` the cause)."""
    return ValueError(f"{path} is not a fricenv regime map ({why})")


def read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` archive at ``path``, by name, without pickle.

    ``ValueError`` naming ``path`` (cause chained) unless the file is an intact archive of
    ``.npy`` arrays of plain dtypes; the ``OSError`` of a path that cannot be opened.
    """
    with open(path, "rb") as fh:  # (FileNotFoundError, IsADirectoryError, PermissionError)
        size = os.fstat(fh.fileno()).st_size
        try:
            with zipfile.ZipFile(fh) as zf:
                return {info.filename[:-4]: _read_member(zf, info, size)
                        for info in zf.infolist()}
        except Exception as exc:  # whatever a damaged archive makes its parsers raise
            why = str(exc) if isinstance(exc, _Damage) else f"{type(exc).__name__}: {exc}"
            raise not_a_map(path, why) from exc


def _read_member(zf: zipfile.ZipFile, info: zipfile.ZipInfo, size: int) -> np.ndarray:
    """One ``.npy`` member, its sizes checked before anything is allocated."""
    name = info.filename
    if not name.endswith(".npy"):
        raise _Damage(f"member {name!r} is not a .npy array")
    if info.compress_size > size or info.file_size > MAX_INFLATION * max(info.compress_size,
                                                                         1):
        raise _Damage(f"member {name!r} claims {info.file_size} bytes from "
                         f"{info.compress_size} in a file of {size}")
    with zf.open(info) as m:
        version = np.lib.format.read_magic(m)
        if version == (1, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_1_0(m)
        elif version == (2, 0):
            shape, fortran, dtype = np.lib.format.read_array_header_2_0(m)
        else:
            raise _Damage(f"member {name!r}: unsupported .npy version {version}")
        if dtype.hasobject:
            raise _Damage(f"unreadable array {name[:-4]!r}: it holds Python objects "
                             "(pickled), which a map never does")
        count = 1
        for n in shape:
            count *= n
        header = m.tell()
        if count * dtype.itemsize != info.file_size - header:
            raise _Damage(f"member {name!r} declares {count * dtype.itemsize} bytes of "
                             f"data ({dtype}, shape {shape}) but holds "
                             f"{info.file_size - header}")
        flat = np.empty(count, dtype=dtype)
        got = m.readinto(flat.view(np.uint8)) if flat.nbytes else 0  # type: ignore[attr-defined]
        if got != flat.nbytes or m.read(1):  # (reading to the end checks the CRC)
            raise _Damage(f"member {name!r} holds {got} bytes of data, not {flat.nbytes}")
    if fortran:
        return flat.reshape(shape[::-1]).transpose()
    return flat.reshape(shape)


# -- the writer lock ---------------------------------------------------------------------
#: Lock files this process holds, by (resolved path, thread), with how many holders nest
#: in each: a save inside a sweep shares the sweep's lock, another thread's is refused.
_HELD: dict[tuple[str, int], int] = {}


def lock_path(path: Path) -> Path:
    """The lock file of the map at ``path``."""
    return path.with_name(path.name + LOCK_SUFFIX)


def _key(lock: Path) -> tuple[str, int]:
    return os.path.join(os.path.realpath(lock.parent), lock.name), threading.get_ident()


def _owner(fd: int) -> str:
    """Who holds the lock, as its holder wrote it ('' if unreadable)."""
    try:
        return os.pread(fd, 200, 0).decode("utf-8", "replace").strip()
    except (OSError, AttributeError):  # (no pread on Windows)
        return ""


def _try_lock(fd: int) -> bool:
    """Take the exclusive lock on ``fd`` without waiting; False if another holds it."""
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        else:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except (BlockingIOError, PermissionError):
        return False
    return True


def _acquire(lock: Path, map_path: Path) -> int:
    """Open and lock ``lock``; :class:`MapInUseError` if another process holds it."""
    lock.parent.mkdir(parents=True, exist_ok=True)  # (as a save would make it)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        if not _try_lock(fd):
            owner = _owner(fd)
            os.close(fd)
            raise MapInUseError(
                f"{map_path} is being written by another sweep ({owner or 'another process'}"
                f", lock {lock.name}); wait for it to finish, or write to another path")
        # The holder before us may have removed the file between our open and our lock:
        # then we hold a lock on a file no one else will find. Start again.
        try:
            same = os.path.samestat(os.stat(lock), os.fstat(fd))
        except FileNotFoundError:
            same = False
        if same:
            os.ftruncate(fd, 0)
            os.write(fd, f"process {os.getpid()} on {socket.gethostname()}\n".encode())
            return fd
        os.close(fd)


@contextlib.contextmanager
def writer_lock(path: Path) -> Iterator[None]:
    """Hold the writer lock of the map at ``path`` for the ``with`` block (at once, or
    :class:`MapInUseError`). Nested holders in this process share the one lock.

    The lock is the one of the resolved path (symlinks followed): two writers reaching one
    map through a symlink and its target, or through two symlinks, take the same lock
    (the lock of the path as given let each believe it was alone)."""
    path = Path(os.path.realpath(path))
    lock = lock_path(path)
    key = _key(lock)
    if key in _HELD:
        _HELD[key] += 1
        try:
            yield
        finally:
            _HELD[key] -= 1
        return
    fd = _acquire(lock, path)
    _HELD[key] = 1
    try:
        yield
    finally:
        del _HELD[key]
        if fcntl is not None:  # removed while still locked: no one can take it in between
            with contextlib.suppress(OSError):
                lock.unlink()
        os.close(fd)  # (releases the lock)
