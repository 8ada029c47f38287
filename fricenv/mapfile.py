"""Regime-map files: reading an archive that may be damaged.

Reading. ``numpy.load`` trusts the archive: a damaged one fails with whatever its parsers
meet first (``EOFError`` for an empty file, ``BadZipFile``, ``NotImplementedError``,
``tokenize.TokenError``, ``OSError``...), and a size field changed by one byte can ask
for terabytes. :func:`read_npz` checks each member's zip entry and ``.npy`` header
against the bytes actually there before it allocates anything, reads the data through the
zip's CRC check, and turns any failure into ``ValueError: <file> is not a fricenv regime
map (<cause>)`` with the cause chained. A path that cannot be opened (missing, a folder,
no permission) keeps its own ``OSError``: it is a path to fix, not a file to distrust.
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

#: Most bytes a member may inflate to per compressed byte: deflate's own limit is 1032.
#: A larger claim is damage (and would have the reader allocate for it).
MAX_INFLATION = 1100
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
        got = m.readinto(flat.view(np.uint8)) if flat.nbytes else 0
        if got != flat.nbytes or m.read(1):  # (reading to the end checks the CRC)
            raise _Damage(f"member {name!r} holds {got} bytes of data, not {flat.nbytes}")
    if fortran:
        return flat.reshape(shape[::-1]).transpose()
    return flat.reshape(shape)

