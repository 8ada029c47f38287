"""Numba's on-disk cache, kept fresh across the package's modules.

numba stamps a cached function with its own source file only, so a function that inlines
functions or constants from another module was loaded stale after that module changed
(numba issue #1833): after an edit of a ``fricenv/core/`` module, the environments' kernels,
which inline its functions, would keep the old physics until the cache was deleted by
hand. ``install`` stamps every cached function of a package with one digest of all the
package's sources instead, so an edit anywhere in it recompiles what was cached from it.
Cache directories stay where numba would put them. :mod:`fricenv.jit` calls it on import,
before any kernel is decorated.
"""

from __future__ import annotations

import functools
import hashlib
from pathlib import Path
from typing import Any


def _locator_classes() -> Any:
    """numba's list of cache locator classes (None on a numba without it). numba is
    imported here, not at the top, so that :func:`source_digest` loads none of it:
    :mod:`fricenv.jit` imports numba first (see its docstring)."""
    from numba.core import caching

    # (numba < 0.62 names the class _CacheImpl)
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    return getattr(impl, "_locator_classes", None)


def source_digest(package_dir: Path) -> str:
    """SHA-256 over the package's ``.py`` files (relative paths and contents)."""
    digest = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        digest.update(path.relative_to(package_dir).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return digest.hexdigest()


def installed_for(package_dir: str | Path) -> bool:
    """Whether ``install`` took effect for ``package_dir``."""
    root = Path(package_dir).resolve()
    classes = _locator_classes() or ()
    return any(getattr(cls, "package_dir", None) == root for cls in classes)


def install(package_dir: str | Path) -> bool:
    """Key the numba cache of every function defined under ``package_dir`` on the
    package's source digest. Call it before those functions are decorated (their cache
    picks its locator then). Idempotent; returns False, changing nothing, on a numba
    without the locator list this relies on (its per-file stamps then apply)."""
    from numba.core import caching

    root = Path(package_dir).resolve()
    classes = _locator_classes()
    if not isinstance(classes, list):
        return False
    if installed_for(root):
        return True
    stamp = source_digest(root)
    numba_locators = list(classes)

    @functools.cache
    def ours(py_file: str) -> bool:
        """Whether ``py_file`` lies in the package (asked once per file, not per kernel:
        resolving the path was a third of the time of decorating a kernel)."""
        try:
            Path(py_file).resolve().relative_to(root)
        except (ValueError, OSError):
            return False
        return True

    class PackageLocator(caching._CacheLocator):
        """numba's own locator for the file, with the package's digest as its stamp."""

        package_dir = root

        def __init__(self, inner: caching._CacheLocator) -> None:
            self._inner = inner
            self._py_file = getattr(inner, "_py_file", None)  # numba's warnings read it

        @classmethod
        def from_function(cls, py_func, py_file):
            if not ours(str(py_file)):
                return None  # numba's own locators take it
            for locator_class in numba_locators:
                inner = locator_class.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
            return None

        def ensure_cache_path(self):
            return self._inner.ensure_cache_path()

        def get_cache_path(self):
            return self._inner.get_cache_path()

        def get_source_stamp(self):
            return stamp

        def get_disambiguator(self):
            return self._inner.get_disambiguator()

    classes.insert(0, PackageLocator)
    return True

