"""The map model: immutable values for maps, scans and objects."""

from mapkit.model.map import (
    CATEGORIES,
    INFO_KEYWORDS,
    InfoLine,
    MapData,
    Provenance,
    Scan,
    ScanHeader,
)
from mapkit.model.objects import (
    BUILTIN_LINE_TYPES,
    BUILTIN_POINT_TYPES,
    BUILTIN_RECT_TYPES,
    MapObject,
    normalize_theta,
)

__all__ = [
    "BUILTIN_LINE_TYPES",
    "BUILTIN_POINT_TYPES",
    "BUILTIN_RECT_TYPES",
    "CATEGORIES",
    "INFO_KEYWORDS",
    "InfoLine",
    "MapData",
    "MapObject",
    "Provenance",
    "Scan",
    "ScanHeader",
    "normalize_theta",
]
