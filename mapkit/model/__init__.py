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
from mapkit.model.scan import (
    LaserConfig,
    LaserLog,
    LaserScan,
    LogEvent,
    LogHeader,
    LogRecord,
    Pose2D,
)

__all__ = [
    "BUILTIN_LINE_TYPES",
    "BUILTIN_POINT_TYPES",
    "BUILTIN_RECT_TYPES",
    "CATEGORIES",
    "INFO_KEYWORDS",
    "InfoLine",
    "LaserConfig",
    "LaserLog",
    "LaserScan",
    "LogEvent",
    "LogHeader",
    "LogRecord",
    "MapData",
    "MapObject",
    "Pose2D",
    "Provenance",
    "Scan",
    "ScanHeader",
    "normalize_theta",
]
