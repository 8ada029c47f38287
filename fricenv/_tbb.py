"""Load Intel TBB, numba's thread-safe and fork-safe threading layer, where numba finds it.

The ``tbb`` wheel installs ``libtbb`` into ``<prefix>/lib``, where the dynamic loader does
not look (a virtual environment, a pyenv or python.org Python), and numba's extension asks
the loader for it by its soname only. :func:`preload` loads the library by its absolute
path from where the wheel's file list says it is, or else from the ``lib`` directories of
``sys.prefix``, ``sys.base_prefix`` and the site-packages; the soname then resolves to the
library already loaded. ``RTLD_LOCAL`` (ctypes' default) is enough for that and exports no
TBB symbols to libraries loaded later.

``import fricenv`` calls it (numba is not imported then): numba chooses its threading layer
when the first parallel kernel of the process starts, and its default order tries TBB
first, so kernels of the user's own that run before any of fricenv's also get TBB.
:mod:`fricenv.jit` then asks for it by name (see there). This module imports only the
standard library.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import site
import sys
from pathlib import Path

#: The file name numba's TBB extension asks the loader for (its soname), per platform.
TBB_LIBRARY = {"win32": "tbb12.dll", "darwin": "libtbb.12.dylib"}.get(sys.platform,
                                                                     "libtbb.so.12")


def _candidates() -> list[Path]:
    """Where the ``tbb`` wheel may have put ``TBB_LIBRARY``, most specific first: the
    wheel's own file list, then the ``lib`` directories of the prefixes and beside the
    site-packages (``<prefix>/lib/pythonX.Y/site-packages`` -> ``<prefix>/lib``)."""
    found: list[Path] = []
    try:
        dist = importlib.metadata.distribution("tbb")
        found += [Path(str(dist.locate_file(f))) for f in dist.files or ()
                  if f.name == TBB_LIBRARY]
    except importlib.metadata.PackageNotFoundError:
        pass
    dirs = [Path(sys.prefix) / "lib", Path(sys.base_prefix) / "lib"]
    packages = [*site.getsitepackages(), site.getusersitepackages()]
    dirs += [Path(p).parent.parent for p in packages]
    found += [d / TBB_LIBRARY for d in dirs]
    unique = dict.fromkeys(p.resolve() for p in found if p.is_file())
    return list(unique)


@functools.cache
def preload() -> str | None:
    """Load ``TBB_LIBRARY`` by its absolute path, once per process; the path that loaded,
    or None if none did (numba then asks the loader, which may still find it)."""
    for path in _candidates():
        try:
            ctypes.CDLL(str(path))
        except OSError:  # another platform's or a broken file: try the next
            continue
        return str(path)
    return None
