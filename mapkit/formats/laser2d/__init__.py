"""ARIA ``.2d`` laser logs: a streaming reader (strict and tolerant) and a writer per version.

Logger versions 1 to 4 are read and written (FORMATS.md part B): v1 (Saphira-era writers: raw
``sick1:`` ranges), v2 (``ArSickLogger``), v3 (ARIA 2.7 ``ArLaserLogger``) and v4 (ARIA 2.8+).
Records come out in one convention whatever the version (see :mod:`mapkit.model.scan`): hit
points in the laser frame, poses as :class:`~mapkit.model.Pose2D`, arrays per scan.

Reading streams: :func:`iter_log` returns a :class:`LogReader` whose ``header`` is read at once and
which yields one record at a time, so a log of any length is read in bounded memory.
:func:`read_log` loads a whole log strictly, :func:`recover_log` tolerantly (bad records are
skipped and reported as :class:`~mapkit.diagnostics.Issue` values with 7xx codes).

Choices where ARIA's writers are ambiguous:

* ``time:`` values are ``<seconds>.<milliseconds>``: v2/v3 do not zero-pad the milliseconds
  (``5.7`` is 5.007 s), v4 does; reading the part after the dot as an integer count of
  milliseconds (when it has at most three digits) is right for both.
* v3 writes raw ranges from the largest angle to the smallest while ``sick1conf:`` lists the
  smallest first; the reader turns that into ``start`` = largest angle, so reading ``i`` is always
  at ``start + i * increment``. In v2 the order cannot be told from the file; it is taken as
  written (first reading at the first ``sick1conf:`` angle).
* Unknown tags never stop the reader: inside a scan record they are kept on the scan
  (:attr:`~mapkit.model.LaserScan.extra`), after ``time:`` and poses they become a ``"tag"``
  event, alone an ``"info"`` event; all are written back. A line that is not a tag (a word ending
  in ``:``), a comment or a ``loop start|stop`` marker is garbage: an error in strict mode, skipped
  and reported in tolerant mode.

Examples:
    >>> text = '''LaserOdometryLog
    ... #Created by ArLaserLogger
    ... version: 4
    ... sick1pose: 100 0 90.00
    ... sick1conf: -90.00 90.00 2
    ... sick1name: laser_1
    ... scan1pose: 100 0 0 90.00
    ... scan1conf: -90.00 90.00 2
    ... scan1name: laser_1
    ... locationTypes: robot robotGlobal
    ... logTime: 0.100
    ... velocities: 0.00 0.00 0.00
    ... scanId: 0
    ... robot: 1000 0 90.00
    ... robotGlobal: 1000 0 90.00
    ... scan1: 500 0  0 0\\x20
    ... # End of log
    ... '''
    >>> log = loads_log(text)
    >>> scan = log.scans[0]
    >>> scan.robot, scan.valid.tolist()
    (Pose2D(x=1000.0, y=0.0, th=90.0), [True, False])
    >>> scan.global_points(log.header.laser(1)).round(6).tolist()
    [[500.0, 100.0]]
    >>> dumps_log(log) == text
    True
"""

from __future__ import annotations

from mapkit.formats.laser2d.common import (
    VERSIONS,
)
from mapkit.formats.laser2d.events import (
    goal_event,
    goal_fields,
    loop_event,
)
from mapkit.formats.laser2d.load import (
    iter_log,
    loads_log,
    log_summary,
    read_log,
    recover_log,
)
from mapkit.formats.laser2d.reader import (
    LogReader,
)
from mapkit.formats.laser2d.writer import (
    LogWriter,
    dumps_log,
    write_log,
)

__all__ = [
    "VERSIONS",
    "LogReader",
    "LogWriter",
    "dumps_log",
    "goal_event",
    "goal_fields",
    "iter_log",
    "loads_log",
    "log_summary",
    "loop_event",
    "read_log",
    "recover_log",
    "write_log",
]
