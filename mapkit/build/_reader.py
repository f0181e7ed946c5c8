"""``mapkit convert`` reads a ``.2d`` log as the map built from it."""

from __future__ import annotations

from mapkit._typing import PathLike
from mapkit.build.builder import build_map
from mapkit.model import MapData


def _read_2d_as_map(path: PathLike) -> MapData:
    """``mapkit convert LOG.2d OUT``: the raw odometry map (no registration; see
    ``mapkit build``)."""
    return build_map(path, register=False).map


def _register_reader() -> None:
    from mapkit.formats.registry import register_reader

    register_reader(".2d", _read_2d_as_map)


_register_reader()
