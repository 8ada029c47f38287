"""Numba's on-disk cache, kept fresh across the package's modules and shared by every
copy of the package on the machine.

numba stamps a cached function with its own source file only, so a function that inlines
functions or constants from another module was loaded stale after that module changed
(numba issue #1833): edit ``core/state.py``, and the environments' kernels kept the old
physics until the cache was deleted by hand. ``install`` stamps every cached function of a
package with one digest of all the package's sources instead, so an edit anywhere in it
recompiles what was cached from it.

It also chooses where the cache lives. numba keeps it beside each source file
(``__pycache__``) or, with ``NUMBA_CACHE_DIR``, in a folder named after a hash of each
source file's absolute path: either way a new virtual environment or a reinstall starts
from an empty cache. Unless ``NUMBA_CACHE_DIR`` is set, ``install`` puts the package's
kernels in one per-user folder keyed on what makes machine code valid, the numba version
and the source digest: ``$XDG_CACHE_HOME/<package>/numba/<numba version>-<digest>/`` (by
default ``~/.cache/...``), with the package's own subfolders inside (``core/``, ``envs/``,
...), so no path depends on where the package is installed. numba's index keys add the
Python version, the machine (CPU name and features) and hashes of the function's bytecode
and closure, nothing that names a path, so a second copy of the same source, in another
venv or checkout, loads what the first compiled. With ``NUMBA_CACHE_DIR`` set, or where
the per-user folder cannot be written, numba's own locations apply.

A folder per digest means every edit of the package starts a new one. ``install`` removes
the folders of other digests that no process has used for ``PRUNE_AFTER_S``, keeping the
``KEEP_DIGESTS`` most recently used in any case.

Damage. numba trusts its files: an empty or garbled index (``.nbi``) raised ``EOFError``,
``UnpicklingError`` or ``UnicodeDecodeError`` from every call of the kernel until the
folder was deleted by hand (numba's own save reads the index first, so it never repaired
it), and flipped bits in a data file (``.nbc``) reached the machine code and crashed the
process. For the package's kernels an unreadable index or data file is a cache miss: the
kernel compiles, its files are written anew, and one line on stderr (a
:class:`NumbaCacheWarning`) names the damaged folder. Every index and data file ends in a
seal, a BLAKE2b digest of its name and bytes written in the same atomic write (so two
processes filling one cache never leave a file and its digest apart); a file is unpickled
only if it matches its seal.

Read-only. Where no location can be written (neither the per-user folder nor numba's
own), a folder that exists is still read: a warm cache baked into an image, or shared
with workers that run as another user, loads as it is. Kernels not in it, or with no
cache at all, compile in memory for the process, which says so once (the same warning);
numba used to raise ``cannot cache function ... no locator available`` instead.

:mod:`fricenv.jit` calls :func:`install` on import, before any kernel is decorated. numba
is imported only inside the functions that need it, so that :func:`source_digest` (the
compile notice, ``fricenv warmup --print-digest``) loads none of it.
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
import pickle
import shutil
import time
import warnings
from pathlib import Path
from typing import Any


class NumbaCacheWarning(UserWarning):
    """numba's cache of the package's kernels is damaged or cannot be written: the
    kernels compile (and the results are the same), but the cache does not save the
    time it should."""


def _warn(message: str) -> None:
    """One line on stderr (``fricenv: NumbaCacheWarning: ...``): a warning attributed to
    no source line, so none is printed under it; filters apply as to any warning."""
    warnings.warn_explicit(message, NumbaCacheWarning, "fricenv", 0)

#: What ends each index and data file of the package's kernels: this mark, then the hex
#: BLAKE2b digest (128 bits) of the file's name and of the bytes before the mark.
SEAL_MARK = b"\nfricenv-blake2b:"
SEAL_SIZE = len(SEAL_MARK) + 32
#: Cache folders of the package's kernels (the checks apply there only).
_OURS: set[str] = set()
#: Folders reported damaged in this process (each is named once).
_REPORTED: set[str] = set()
#: Whether this process said that it compiles in memory (said once).
_IN_MEMORY: list[str] = []


def _locator_classes() -> Any:
    """numba's list of cache locator classes (None on a numba without it)."""
    from numba.core import caching

    # (numba < 0.62 names the class _CacheImpl)
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    return getattr(impl, "_locator_classes", None)

#: Digest folders always kept, the most recently used first (one per source in use).
KEEP_DIGESTS = 4
#: Seconds after its last use from which another digest's folder may be removed: a
#: process that imported the package earlier may still save kernels into it (numba then
#: recreates the folder, so removing one in use costs only compile time).
PRUNE_AFTER_S = 3600.0


def source_digest(package_dir: Path) -> str:
    """SHA-256 over the package's ``.py`` files (relative paths and contents)."""
    digest = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        digest.update(path.relative_to(package_dir).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()


def _numba_cache_dir() -> str:
    """``NUMBA_CACHE_DIR`` as numba read it ("" when unset)."""
    import numba

    return str(getattr(numba.config, "CACHE_DIR", "") or "")


def user_cache_root() -> Path:
    """The per-user cache base: ``$XDG_CACHE_HOME`` if set to an absolute path, else
    ``~/.cache`` (the XDG base directory rule)."""
    configured = os.environ.get("XDG_CACHE_HOME", "")
    if configured and os.path.isabs(configured):
        return Path(configured)
    return Path.home() / ".cache"  # (RuntimeError where no home directory is known)


def user_cache_dir(package_dir: str | Path, digest: str) -> Path:
    """The per-user folder of the package at ``package_dir`` with source ``digest``."""
    import numba

    name = Path(package_dir).resolve().name
    return user_cache_root() / name / "numba" / f"{numba.__version__}-{digest}"


def installed_for(package_dir: str | Path) -> bool:
    """Whether ``install`` took effect for ``package_dir``."""
    return _locator_for(package_dir) is not None


def cache_dir_for(package_dir: str | Path) -> Path | None:
    """The per-user folder ``install`` keeps the kernels of ``package_dir`` in, or None
    where numba's own locations apply (``NUMBA_CACHE_DIR`` set, no ``install``, or the
    folder not writable)."""
    folder = getattr(_locator_for(package_dir), "user_dir", None)
    if not isinstance(folder, Path) or _numba_cache_dir() or not os.access(folder, os.W_OK):
        return None
    return folder


def _locator_for(package_dir: str | Path) -> type | None:
    root = Path(package_dir).resolve()
    for cls in _locator_classes() or ():
        if getattr(cls, "package_dir", None) == root:
            return cls
    return None


def _prune(parent: Path, current: Path) -> None:
    """Remove the digest folders beside ``current`` unused for PRUNE_AFTER_S, beyond the
    KEEP_DIGESTS most recently used. Best effort: the cache stays valid if this fails."""
    try:
        folders = sorted((p for p in parent.iterdir() if p.is_dir() and p != current),
                         key=lambda p: p.stat().st_mtime, reverse=True)
        now = time.time()
        for old in folders[KEEP_DIGESTS - 1:]:
            if now - old.stat().st_mtime > PRUNE_AFTER_S:
                shutil.rmtree(old, ignore_errors=True)
    except OSError:
        pass


def _mark_used(user_dir: Path) -> None:
    """Create ``user_dir`` if needed and mark it used now (its mtime); prune the other
    digests' folders when it is new."""
    try:
        new = not user_dir.exists()
        user_dir.mkdir(parents=True, exist_ok=True)
        os.utime(user_dir)
    except OSError:
        return  # not writable: the functions fall back to numba's own locations
    if new:
        _prune(user_dir.parent, user_dir)


def seal(name: str, payload: bytes) -> bytes:
    """``payload`` with its seal appended: the digest binds the bytes to the file's name
    (an index names its data files: a data file put in another's place fails too)."""
    digest = hashlib.blake2b(name.encode() + b"\0" + payload, digest_size=16).hexdigest()
    return payload + SEAL_MARK + digest.encode("ascii")


def unseal(name: str, data: bytes) -> bytes:
    """The payload of a sealed file, or :class:`_Damaged` saying what is wrong."""
    if len(data) < SEAL_SIZE or data[-SEAL_SIZE:-32] != SEAL_MARK:
        raise _Damaged(f"{name} has no seal (empty, cut short, or not written by fricenv)")
    payload = data[:-SEAL_SIZE]
    if seal(name, payload) != data:
        raise _Damaged(f"{name} does not match its seal")
    return payload


def _report_damage(folder: str, file: str, exc: BaseException) -> None:
    """One WARNING line per damaged folder and process."""
    if folder in _REPORTED:
        return
    _REPORTED.add(folder)
    _warn(f"numba's cache in {folder} is damaged ({file}: {type(exc).__name__}: {exc}); "
          "its kernels compile again and replace it")


def _report_in_memory(folder: str, exc: BaseException) -> None:
    """One WARNING line per process: the kernels compile, but are kept in memory only."""
    if _IN_MEMORY:
        return
    _IN_MEMORY.append(folder)
    _warn(f"no writable numba cache ({folder}: {exc}); kernels not cached there compile "
          "in memory, for this process only (set NUMBA_CACHE_DIR to a writable folder to "
          "keep them)")


class _Damaged(OSError):
    """A data file that fails its digest or cannot be unpickled (an ``OSError``, which
    numba's ``IndexDataCacheFile.load`` turns into a cache miss)."""


def _stale_index(raw: bytes, version: str, stamp: str) -> bool:
    """Whether an index that fails its seal is one numba wrote for another numba version
    or source (in a ``NUMBA_CACHE_DIR`` or ``__pycache__`` folder that an older fricenv
    filled): a plain miss, not damage to report."""
    try:
        stream = io.BytesIO(raw)
        if pickle.load(stream) != version:
            return True
        return bool(pickle.loads(stream.read())[0] != stamp)
    except Exception:  # (unreadable: damage)
        return False


def _guard_cache_files(caching: Any) -> None:
    """For the package's kernels (folders in ``_OURS``): seal each index and data file
    numba writes (:func:`seal`, in the same atomic write, so concurrent writers never
    leave a file and its digest apart), check the seal before unpickling, treat any
    damage as a cache miss named once, and turn a save that cannot write into in-memory
    compilation. Other packages' caches are left as numba handles them."""
    cls = caching.IndexDataCacheFile
    if getattr(cls, "_fricenv_guarded", False):
        return
    load_index, save_index, load_data = cls._load_index, cls._save_index, cls._load_data
    save, save_data = cls.save, cls._save_data

    def _load_index(self: Any) -> dict:
        if self._cache_path not in _OURS:
            return load_index(self)
        try:
            with open(self._index_path, "rb") as f:
                raw = f.read()
        except FileNotFoundError:
            return {}
        try:  # (numba's own reading, on the checked payload)
            stream = io.BytesIO(unseal(self._index_name, raw))
            if pickle.load(stream) != self._version:
                return {}
            stamp, overloads = pickle.loads(stream.read())
            if not isinstance(overloads, dict):
                raise _Damaged(f"{self._index_name} holds no index")
        except Exception as exc:  # (EOFError, UnpicklingError, UnicodeDecodeError, ...)
            if not _stale_index(raw, self._version, self._source_stamp):
                _report_damage(self._cache_path, self._index_name, exc)
            return {}
        return overloads if stamp == self._source_stamp else {}

    def _save_index(self: Any, overloads: dict) -> None:
        if self._cache_path not in _OURS:
            return save_index(self, overloads)
        payload = (pickle.dumps(self._version, protocol=-1)
                   + self._dump((self._source_stamp, overloads)))
        with self._open_for_write(self._index_path) as f:
            f.write(seal(self._index_name, payload))
        return None

    def _load_data(self: Any, name: str) -> Any:
        if self._cache_path not in _OURS:
            return load_data(self, name)
        with open(self._data_path(name), "rb") as f:  # (OSError: numba's load() misses)
            raw = f.read()
        try:
            return pickle.loads(unseal(name, raw))
        except Exception as exc:  # (a flipped bit never reaches the machine code)
            _report_damage(self._cache_path, name, exc)
            raise _Damaged(f"{name}: {exc}") from exc

    def _save_data(self: Any, name: str, data: Any) -> None:
        if self._cache_path not in _OURS:
            return save_data(self, name, data)
        with self._open_for_write(self._data_path(name)) as f:
            f.write(seal(name, self._dump(data)))
        return None

    def _save(self: Any, key: Any, data: Any) -> None:
        if self._cache_path not in _OURS:
            return save(self, key, data)
        try:
            return save(self, key, data)
        except OSError as exc:  # read-only or missing folder: the compiled kernel stays
            _report_in_memory(self._cache_path, exc)
            return None

    cls._load_index, cls._save_index = _load_index, _save_index
    cls._load_data, cls._save_data, cls.save = _load_data, _save_data, _save
    cls._fricenv_guarded = True


def install(package_dir: str | Path) -> bool:
    """Key the numba cache of every function defined under ``package_dir`` on the
    package's source digest, in the per-user folder unless ``NUMBA_CACHE_DIR`` is set.
    Call it before those functions are decorated (their cache picks its locator then).
    Idempotent; returns False, changing nothing, on a numba without the locator list this
    relies on (its per-file stamps and locations then apply)."""
    from numba.core import caching

    root = Path(package_dir).resolve()
    classes = _locator_classes()
    if not isinstance(classes, list):
        return False
    if installed_for(root):
        return True
    stamp = source_digest(root)
    numba_locators = list(classes)
    _guard_cache_files(caching)
    try:
        folder: Path | None = user_cache_dir(root, stamp)
    except RuntimeError:  # no home directory: numba's own locations
        folder = None
    if folder is not None and not _numba_cache_dir():
        _mark_used(folder)

    @functools.cache
    def relative(py_file: str) -> Path | None:
        """``py_file`` relative to the package, None if it lies outside (asked once per
        file, not per kernel: resolving the path was a third of decorating a kernel)."""
        try:
            return Path(py_file).resolve().relative_to(root)
        except (ValueError, OSError):
            return None

    class PackageLocator(caching._CacheLocator):
        """The package's digest as the stamp; the per-user folder (the source file's
        folder relative to the package inside it) or else numba's own locator's path."""

        package_dir = root
        user_dir = folder

        def __init__(self, py_func, py_file: str, path: str | None,
                     inner: caching._CacheLocator | None) -> None:
            self._py_file = py_file  # numba's warnings read it
            self._lineno = py_func.__code__.co_firstlineno
            self._path = path
            self._inner = inner

        @classmethod
        def from_function(cls, py_func, py_file):
            """The first writable location: the per-user folder, else numba's own; where
            none is, the first that exists (read as it is), else an in-memory one (its
            folder is never made: loads miss, saves say once that they cannot write)."""
            rel = relative(str(py_file))
            if rel is None:
                return None  # not ours: numba's own locators take it
            own = None
            if folder is not None and not _numba_cache_dir():
                own_path = str(folder.joinpath(*rel.parent.parts))
                own = cls(py_func, py_file, own_path, None)
                try:
                    caching._CacheLocator.ensure_cache_path(own)  # (numba's: raises)
                    return own
                except OSError:
                    if os.path.isdir(own_path):
                        return own  # a warm cache that cannot be written: read it
            for locator_class in numba_locators:
                inner = locator_class.from_function(py_func, py_file)
                if inner is not None:
                    return cls(py_func, py_file, None, inner)
            existing = _existing_numba_path(numba_locators, py_func, py_file)
            if existing is not None:
                return cls(py_func, py_file, existing, None)
            if own is not None:
                return own
            return cls(py_func, py_file, str(Path(py_file).parent / "__pycache__"), None)

        def ensure_cache_path(self):
            """Make the folder, or say once that nothing can be written (numba's save
            calls this first and would raise from the kernel's first call)."""
            try:
                super().ensure_cache_path()
            except OSError as exc:
                _report_in_memory(self.get_cache_path(), exc)

        def get_cache_path(self):
            path = self._path if self._inner is None else self._inner.get_cache_path()
            _OURS.add(str(path))  # (the folders whose files are sealed and checked)
            return path

        def get_source_stamp(self):
            return stamp

        def get_disambiguator(self):
            # numba's own: the first line number (the file name is in the index's name)
            return str(self._lineno) if self._inner is None else self._inner.get_disambiguator()

    classes.insert(0, PackageLocator)
    return True


def _existing_numba_path(locators: list, py_func: Any, py_file: str) -> str | None:
    """The folder of the first of numba's ``locators`` that exists for the function,
    writable or not (a locator that cannot even be made for it is skipped)."""
    for locator_class in locators:
        try:
            path = locator_class(py_func, py_file).get_cache_path()
        except Exception:  # (locators for other kinds of file)
            continue
        if isinstance(path, str) and os.path.isdir(path):
            return path
    return None

