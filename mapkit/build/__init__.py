"""Build a ``.map`` from a ``.2d`` laser log, as Mapper3 did.

The pipeline (:func:`build_map`):

1. **Odometry replay**: each scan's ``robot:`` pose (or ``robotGlobal:``) gives the motion since
   the previous scan.
2. **Scan-to-map registration**: each scan is matched by point-to-line ICP (scipy's ``cKDTree``)
   against a local map made of the scans registered just before it, starting from the pose
   odometry predicts.
3. **Loop closure**: a ``loop: start K`` / ``loop: stop K`` pair in the log says the robot came
   back where it was; revisits are also detected (the robot is near a pose it had long before).
   Each is matched (a correlative search, then ICP) and becomes an edge of a pose graph, which is
   optimised (sparse Gauss-Newton) when it moves poses noticeably, and once at the end.
4. **Map**: every scan's points through its final pose, quantised to the resolution lattice
   (20 mm, as ARIA maps), cells hit too rarely dropped, walls thinned to the cells hit most; the
   points are sorted as ARIA's are.
5. **Lines**: segments fitted to the points (direction bins, split at gaps and corners, merge).
6. **Objects**: ``cairn:`` goal events become ``GoalWithHeading`` objects at their corrected
   pose; the first scan's pose becomes ``RobotHome``.

``register=False`` skips 2 and 3: the map of raw odometry.

Examples:
    >>> from mapkit.model import MapData, Scan
    >>> from mapkit.simulate import simulate_log
    >>> room = Scan.from_arrays(lines=[[0, 0, 8000, 0], [8000, 0, 8000, 5000],
    ...                                [8000, 5000, 0, 5000], [0, 5000, 0, 0]])
    >>> sim = simulate_log(MapData(scans=(room,)), start=(1500, 2500, 0),
    ...                    waypoints=[(6500, 2500), (6500, 1500)], seed=2)
    >>> result = build_map(sim.log)
    >>> m = result.map
    >>> m.scan.resolution, m.scan.points_sorted, len(m.lines) >= 3, m.objects[0].type
    (20, True, True, 'RobotHome')
"""

from __future__ import annotations

from mapkit.build._common import (
    FloatArray as FloatArray,
    Progress as Progress,
)
from mapkit.build._lines import extract_lines
from mapkit.build._reader import _register_reader as _register_reader  # registers the .2d reader
from mapkit.build.builder import (
    BuildResult,
    TurnEvidence,
    build_map,
    robot_turn_error,
)

__all__ = ["BuildResult", "TurnEvidence", "build_map", "extract_lines", "robot_turn_error"]
