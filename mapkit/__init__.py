"""mapkit: ARIA/ARNL maps and laser logs for Python, and the bridge to ROS.

Read, write, edit, validate, rasterise and transfer ARIA ``.map`` files (categories ``2D-Map`` to
``2D-Map-Ex4``) and ``.2d`` laser logs.

Examples:
    >>> import mapkit
    >>> m = mapkit.loads("2D-Map\\nCairn: Goal 1000 2000 0 \\"\\" ICON \\"Desk\\"\\nDATA\\n5 5\\n")
    >>> m.objects[0].name, m.points.tolist()
    ('Desk', [[5, 5]])
    >>> print(mapkit.dumps(m), end="")
    2D-Map
    MinPos: 0 0
    MaxPos: 5 5
    NumPoints: 1
    PointsAreSorted: false
    Resolution: 0
    Cairn: Goal 1000 2000 0.000000 "" ICON "Desk"
    DATA
    5 5
"""

from __future__ import annotations

import logging

__version__ = "0.1.0"

from mapkit.diagnostics import Issue, IssueCode, Location, Report, Severity
from mapkit.errors import (
    ChecksumError,
    EditError,
    FormatError,
    LocalTransferError,
    LogFormatError,
    MapFormatError,
    MapkitError,
    RemoteTransferError,
    TransferError,
    UnsupportedFormatError,
)
from mapkit.formats.map import dumpb, dumps, load, loads, recover, save
from mapkit.model import MapData, MapObject, Provenance, Scan, ScanHeader

logging.getLogger(__name__).addHandler(logging.NullHandler())


def __getattr__(name: str) -> object:
    """Submodules loaded on first use: ``mapkit.aria`` (ARNL/ARAM robots over ArNetworking)."""
    if name == "aria":
        import importlib

        return importlib.import_module("mapkit.aria")
    raise AttributeError(f"module 'mapkit' has no attribute {name!r}")

__all__ = [
    "BuildResult",
    "MapDiff",
    "Region",
    "build_map",
    "diff",
    "iter_log",
    "read_log",
    "recover_log",
    "simulate_log",
    "validate",
    "write_log",
    "ChecksumError",
    "EditError",
    "FormatError",
    "Issue",
    "IssueCode",
    "LocalTransferError",
    "Location",
    "LogFormatError",
    "MapData",
    "MapFormatError",
    "MapObject",
    "MapkitError",
    "Provenance",
    "RemoteTransferError",
    "Report",
    "Scan",
    "ScanHeader",
    "Severity",
    "TransferError",
    "UnsupportedFormatError",
    "__version__",
    "dumpb",
    "dumps",
    "load",
    "loads",
    "recover",
    "save",
]
