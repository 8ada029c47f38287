"""Regime atlases: regime maps over any volume of parameters, on one machine or a Dask
cluster, into labelled, resumable Zarr stores.

``fricenv.atlas(base, axes, path=None, client=None, chunks=None, settings=None,
progress=True)`` -> ``xarray.Dataset``: this module is callable, so that ``fricenv.atlas``
is both the function and the package (``python -m fricenv.atlas`` is its command line).
See :func:`fricenv.atlas.api.atlas` and docs/atlas.md.

Layers: :mod:`.core` (grid, validation, chunks, local execution; numpy only),
:mod:`.store` (xarray and Zarr), :mod:`.distributed` (Dask, imported only with a client),
:mod:`.views` (matplotlib), :mod:`.cli`.
"""

from __future__ import annotations

import inspect
import sys
import types

from .api import atlas
from .core import AXIS_FIELDS
from .store import open_atlas, regime_map_dataset

__all__ = ["AXIS_FIELDS", "atlas", "onset_surface_figure", "open_atlas", "plot_slice",
           "regime_map_dataset", "slice_figure", "stick_boundaries"]

_VIEWS = ("plot_slice", "stick_boundaries", "onset_surface_figure", "slice_figure")


def __getattr__(name: str) -> object:
    if name in _VIEWS:  # matplotlib only when a view is asked for
        from . import views

        return getattr(views, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class _CallableModule(types.ModuleType):
    """Importing the package ``fricenv.atlas`` binds it as ``fricenv``'s attribute
    ``atlas``, over any function of that name: so the package itself runs the atlas."""

    def __call__(self, *args: object, **kwargs: object) -> object:
        return atlas(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
__signature__ = inspect.signature(atlas)
