"""Errors of the raster package (all :class:`~mapkit.errors.MapkitError` subclasses)."""

from __future__ import annotations

from mapkit.errors import FormatError, MapkitError

__all__ = ["RasterError", "RosMapError"]


class RasterError(MapkitError, ValueError):
    """A map cannot be rasterised as asked (grid too large, bad resolution, bad option)."""


class RosMapError(FormatError):
    """A ROS map (YAML + image) is not one map_server would load. Says file and line."""
