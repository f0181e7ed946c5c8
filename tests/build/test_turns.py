"""Turns and corridors in registration: a robot that slips in its turns, scans that slide along
a corridor (mapkit/build/_odometry.py, _register.py)."""

from __future__ import annotations

import math

import numpy as np

from mapkit.build import build_map
from mapkit.build._match import MatchResult
from mapkit.build._register import _seen
from mapkit.build.quality import distance_to_segments, trajectory_rms
from mapkit.model import MapData, MapObject, Scan
from mapkit.simulate import simulate_log


def corridor() -> tuple[MapData, list[list[int]]]:
    """A 30 m corridor, 2 m wide, closed at its far end, with a door niche every 6 m."""
    walls = [[0, 0, 30000, 0], [30000, 0, 30000, 2000], [0, 2000, 0, 0]]
    x = 0
    for k in range(5):
        a = k * 6000 + 2500
        walls += [[x, 2000, a, 2000], [a, 2000, a, 2600], [a + 900, 2600, a + 900, 2000]]
        walls.append([a, 2600, a + 900, 2600])
        x = a + 900
    walls.append([x, 2000, 30000, 2000])
    home = MapObject("RobotHome", 1000, 1000, 0, name="Home")
    return MapData(scans=(Scan.from_arrays(lines=walls),), objects=(home,)), walls


def test_u_turn_in_a_dead_end_follows_the_scans() -> None:
    """Down the corridor, round on the spot at its end (slipping 3 % of each turn step) and back.
    The scans see every step of the turn; odometry's word on a turn must not outvote them (with
    one noise scale fitted to the straight steps it did, and the way back came out 11 degrees
    off until the loop closure bent it back)."""
    m, walls = corridor()
    sim = simulate_log(m, waypoints=[(29000, 1000)], loop=True, seed=1, turn_slip=0.03, drift=0.05)
    res = build_map(sim.log, lines=False, loop_closure=False)
    truth = sim.truth[np.searchsorted(sim.truth_ids, res.scan_ids)]
    err = (res.poses[:, 2] - truth[:, 2] + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(err)) < 1.0, np.max(np.abs(err))
    res = build_map(sim.log, lines=False)
    d = distance_to_segments(res.map.points, np.array(walls, dtype=float))
    rms, _ = trajectory_rms(res.poses, sim.truth[np.searchsorted(sim.truth_ids, res.scan_ids)])
    assert rms < 30.0 and np.percentile(d, 90) < 40.0, (rms, np.percentile(d, 90))


def _match(pose: list[float], normals: np.ndarray) -> MatchResult:
    return MatchResult(np.array(pose), True, 0.9, 10.0, 100, 0.0, np.eye(3), normals)


def test_a_scan_sliding_along_a_corridor_still_counts() -> None:
    """A match that slid 600 mm along a corridor (its walls face y only) still fixes the heading
    and the corridor's width; the slide is no evidence and is taken out."""
    pred = np.array([1000.0, 500.0, 0.1])
    corridor_walls = np.diag([0.0, 1.0])  # mean n n^T of the matched normals: all along y
    dv = _seen(_match([1600.0, 504.0, 0.102], corridor_walls), pred, 300.0)
    assert dv is not None
    np.testing.assert_allclose(dv, [0.0, 4.0, 0.002], atol=1e-9)
    # Where the walls hold both directions, 600 mm off odometry is no match.
    room = np.diag([0.5, 0.5])
    assert _seen(_match([1600.0, 504.0, 0.102], room), pred, 300.0) is None
    # Nor is a heading 10 degrees off, corridor or not.
    assert _seen(_match([1000.0, 500.0, 0.1 + math.radians(10)], corridor_walls), pred, 0) is None
    assert _seen(None, pred, 0.0) is None
