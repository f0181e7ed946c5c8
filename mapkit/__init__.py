"""mapkit: ARIA/ARNL maps and laser logs for Python, and the bridge to ROS.

Read, write, edit, validate, rasterise and transfer ARIA ``.map`` files (categories ``2D-Map`` to
``2D-Map-Ex4``) and ``.2d`` laser logs.

Everything in ``__all__`` is reachable as ``mapkit.NAME``, and the subpackages (``mapkit.edit``,
``mapkit.raster``, ``mapkit.build``, ...) as ``mapkit.edit`` etc., without importing them first.
They are imported on first use (``_LAZY`` and ``_SUBMODULES`` below), so ``import mapkit`` and
``mapkit --help`` do not pay for numpy, scipy or matplotlib until something needs them.

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
    >>> m = mapkit.edit.add_goal(m, "Coffee", 3000, 2000)
    >>> [i.code.name for i in mapkit.validate(m, navigation=False).errors]
    []
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

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

__version__ = "0.1.0"

if TYPE_CHECKING:  # what the lazy table below gives, for type checkers and IDEs
    from mapkit import build, edit, formats, model, raster, validate  # noqa: F401
    from mapkit.build import BuildResult, build_map
    from mapkit.diagnostics import Issue, IssueCode, Location, Report, Severity
    from mapkit.edit import MapDiff, Region, diff
    from mapkit.formats.laser2d import iter_log, read_log, recover_log, write_log
    from mapkit.formats.map import dumpb, dumps, load, loads, recover, save
    from mapkit.model import MapData, MapObject, Provenance, Scan, ScanHeader
    from mapkit.simulate import simulate_log

#: Public name -> the module that defines it; imported on first access. To add one: one line here
#: and the name in ``__all__``.
_LAZY: dict[str, str] = {
    # reading and writing maps
    "dumpb": "mapkit.formats.map",
    "dumps": "mapkit.formats.map",
    "load": "mapkit.formats.map",
    "loads": "mapkit.formats.map",
    "recover": "mapkit.formats.map",
    "save": "mapkit.formats.map",
    # the model
    "MapData": "mapkit.model",
    "MapObject": "mapkit.model",
    "Provenance": "mapkit.model",
    "Scan": "mapkit.model",
    "ScanHeader": "mapkit.model",
    # findings
    "Issue": "mapkit.diagnostics",
    "IssueCode": "mapkit.diagnostics",
    "Location": "mapkit.diagnostics",
    "Report": "mapkit.diagnostics",
    "Severity": "mapkit.diagnostics",
    # laser logs
    "iter_log": "mapkit.formats.laser2d",
    "read_log": "mapkit.formats.laser2d",
    "recover_log": "mapkit.formats.laser2d",
    "write_log": "mapkit.formats.laser2d",
    "simulate_log": "mapkit.simulate",
    # building, editing, comparing
    "BuildResult": "mapkit.build",
    "build_map": "mapkit.build",
    "MapDiff": "mapkit.edit",
    "Region": "mapkit.edit",
    "diff": "mapkit.edit",
}

#: Subpackages reachable as ``mapkit.NAME`` after a bare ``import mapkit``. ``mapkit.validate``
#: is both the package and (called) the :func:`mapkit.validate.validate` function.
_SUBMODULES = frozenset(
    {
        "aria",
        "arnet",
        "build",
        "diagnostics",
        "edit",
        "errors",
        "formats",
        "mesh",
        "model",
        "open",
        "raster",
        "render",
        "ros",
        "samples",
        "simulate",
        "transfer",
        "validate",
    }
)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
    elif name in _SUBMODULES:
        value = importlib.import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY, *_SUBMODULES})


logging.getLogger(__name__).addHandler(logging.NullHandler())


__all__ = [
    "BuildResult",
    "ChecksumError",
    "EditError",
    "FormatError",
    "Issue",
    "IssueCode",
    "LocalTransferError",
    "Location",
    "LogFormatError",
    "MapData",
    "MapDiff",
    "MapFormatError",
    "MapObject",
    "MapkitError",
    "Provenance",
    "Region",
    "RemoteTransferError",
    "Report",
    "Scan",
    "ScanHeader",
    "Severity",
    "TransferError",
    "UnsupportedFormatError",
    "__version__",
    "build_map",
    "diff",
    "dumpb",
    "dumps",
    "iter_log",
    "load",
    "loads",
    "read_log",
    "recover",
    "recover_log",
    "save",
    "simulate_log",
    "validate",
    "write_log",
]
