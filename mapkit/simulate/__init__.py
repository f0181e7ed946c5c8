"""Simulate a laser log: drive a robot through a known map and record what a laser would see.

:func:`simulate_log` plans a route through the map (from its goals, or through given waypoints),
drives it, ray-casts a laser against the map's lines and points (vectorised with numpy: each
line or point is turned into the range of beams it covers, then each beam keeps its nearest hit;
a point lying on a line is the same wall scanned, and is left out so walls stay flat),
adds range noise, and integrates odometry with drift. The result holds the log's records (in the
:mod:`mapkit.model.scan` convention) and the **true** pose of every scan.

Where the truth goes: ARIA's ``robotGlobal:`` is the pose corrected by localisation, and when
nothing corrects it the logger writes the odometry pose there too (FORMATS.md B.5a). The
simulator does the same (``robot:`` = ``robotGlobal:`` = odometry), so the log looks like one
recorded by a robot that is being mapped, and writes the true poses to a **sidecar file** beside
the log, ``NAME.truth.tsv`` (one line per scan: ``scanId time x y th``), read back by
:func:`read_truth`. Nothing in the ``.2d`` then tells a map builder the answer.

Examples:
    >>> from mapkit.model import MapData, Scan, MapObject
    >>> room = Scan.from_arrays(lines=[[0, 0, 6000, 0], [6000, 0, 6000, 4000],
    ...                                [6000, 4000, 0, 4000], [0, 4000, 0, 0]])
    >>> m = MapData(scans=(room,), objects=(MapObject("RobotHome", 1000, 1000, 0),))
    >>> sim = simulate_log(m, waypoints=[(5000, 1000), (5000, 3000)], seed=1, range_noise=0)
    >>> scan = sim.log.scans[0]
    >>> round(float(scan.xy[180, 0]) + 160 + 1000)    # the beam straight ahead hits x = 6000
    6000
"""

from __future__ import annotations

from mapkit.simulate.rays import (
    NO_RETURN as NO_RETURN,
    FloatArray as FloatArray,
    ray_cast,
)
from mapkit.simulate.simulation import (
    simulate_log,
)
from mapkit.simulate.truth import (
    SimulatedLog,
    read_truth,
    truth_path_for,
)

__all__ = ["SimulatedLog", "ray_cast", "read_truth", "simulate_log", "truth_path_for"]
