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

:mod:`fricenv.jit` calls :func:`install` on import, before any kernel is decorated. numba
is imported only inside the functions that need it, so that :func:`source_digest` (the
compile notice, ``fricenv warmup --print-digest``) loads none of it.
"""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import time
from pathlib import Path
from typing import Any


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
            rel = relative(str(py_file))
            if rel is None:
                return None  # not ours: numba's own locators take it
            if folder is not None and not _numba_cache_dir():
                own = cls(py_func, py_file, str(folder.joinpath(*rel.parent.parts)), None)
                try:
                    own.ensure_cache_path()
                    return own
                except OSError:
                    pass  # not writable: numba's own locations
            for locator_class in numba_locators:
                inner = locator_class.from_function(py_func, py_file)
                if inner is not None:
                    return cls(py_func, py_file, None, inner)
            return None

        def get_cache_path(self):
            return self._path if self._inner is None else self._inner.get_cache_path()

        def get_source_stamp(self):
            return stamp

        def get_disambiguator(self):
            # numba's own: the first line number (the file name is in the index's name)
            return str(self._lineno) if self._inner is None else self._inner.get_disambiguator()

    classes.insert(0, PackageLocator)
    return True

