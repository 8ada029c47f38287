"""Regime atlases: regime maps over any volume of parameters, on one machine or a Dask
cluster, into labelled, resumable Zarr stores.

``fricenv.atlas(base, axes, path=None, client=None, chunks=None, settings=None,
progress=True)`` -> ``xarray.Dataset``: this module is callable, so that ``fricenv.atlas``
is both the function and the package (``python -m fricenv.atlas`` is its command line).
See :func:`fricenv.atlas.api.atlas` and docs/atlas.md.

An atlas is an ``xarray.Dataset`` whose dimensions are the swept axes, in the order
given, with ``q`` (the tested denominator of each nu) as a coordinate along nu, and whose
data variables come in this order: ``stick_fraction``, ``n_stick``, ``n_reversal``,
``v_min``, ``v_max``, ``period``, ``status``, ``lyapunov``, ``label`` (:data:`.core.VARIABLES`). The
order is the same from :func:`fricenv.atlas`, :func:`fricenv.open_atlas` and plain
``xarray.open_zarr(path)``, which opens a store without a warning (its metadata is
consolidated, in that order).

Layers: :mod:`.core` (grid, validation, chunks, local execution; numpy only),
:mod:`.store` (xarray and Zarr), :mod:`.distributed` (Dask, imported only with a client),
:mod:`.views` (matplotlib); its command line is :mod:`fricenv.cli.atlas`. Names are
resolved on first use, so that importing the package, its core (on a worker) or its
command line (under ``fricenv --help``) loads none of the optional dependencies.
"""

from __future__ import annotations

import importlib
import inspect
import sys
import types
from typing import Any

__all__ = ["AXIS_FIELDS", "atlas", "onset_surface_figure", "open_atlas", "plot_slice",
           "regime_map_dataset", "slice_figure", "stick_boundaries"]

#: Where each public name lives.
_HOMES = {"atlas": "api", "AXIS_FIELDS": "core", "open_atlas": "store",
          "regime_map_dataset": "store", "plot_slice": "views", "slice_figure": "views",
          "stick_boundaries": "views", "onset_surface_figure": "views"}


def _api_atlas() -> Any:
    from .api import atlas

    return atlas


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)
    if name == "__signature__":  # inspect.signature(fricenv.atlas)
        return inspect.signature(_api_atlas())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


class _CallableModule(types.ModuleType):
    """Importing the package ``fricenv.atlas`` binds it as ``fricenv``'s attribute
    ``atlas``, over any function of that name: so the package itself runs the atlas."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        from .api import atlas

        return atlas(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
