"""Loop closure (mapkit/build/_loops.py): revisits matched, checked and added to the pose graph."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from mapkit.build._loops import _good_closure, _share, _within_reach
from mapkit.build._match import icp, widened
from mapkit.build._odometry import _OdometryModel


def _reach(scale: float, steps: int = 150) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Running sums of the odometry's variance over straight 300 mm steps, and the path."""
    model = _OdometryModel(scale=scale)
    info = model.info(300.0, 0.0)
    var = 1.0 / np.diag(info)
    k = np.arange(steps + 1, dtype=float)
    return k * (var[0] + var[1]), k * var[2], k * 300.0


def test_a_closure_beyond_what_odometry_can_be_out_is_refused() -> None:
    """After 45 m of odometry good to a few tenths of a percent (the noise scale at its floor),
    a match that moves the robot 1.8 m is caught on the wrong walls (a corridor like another: a
    simulated columbia log had one, and the loops closed after it started from where it put
    the robot). A few cm, or a few tenths of a degree, is what matches and odometry allow."""
    cum_xy, cum_th, path = _reach(0.01)
    assert not _within_reach((cum_xy, cum_th), 150, 0, path, 1800.0, 0.0)
    assert not _within_reach((cum_xy, cum_th), 150, 0, path, 20.0, math.radians(3.0))
    assert _within_reach((cum_xy, cum_th), 150, 0, path, 60.0, math.radians(0.3))
    # Odometry that slips and drifts (noise scale 1) can be metres out: the match decides.
    cum_xy, cum_th, path = _reach(1.0)
    assert _within_reach((cum_xy, cum_th), 150, 0, path, 1800.0, math.radians(2.0))
    # Over a short gap the reach is short too.
    assert not _within_reach((cum_xy, cum_th), 10, 0, path, 1800.0, 0.0)


def test_an_unmatched_loop_tag_claims_the_place_not_the_heading() -> None:
    """The robot drives 5 m out and back and stops where the ``loop: start`` was, facing the
    other way (a 180-degree laser then sees the other side: the scans do not match). The tag's
    hint says it is back at the same place; it used to say facing the same way too, which the
    consistency check had to switch off (and which pulled the end round until then)."""
    from mapkit.build._graph import PoseGraph, between, sigma_info
    from mapkit.build._register import _hint

    true = [np.zeros(3)]
    for k in range(1, 21):
        if k == 10:
            true.append(np.array([5000.0, 0.0, math.pi]))  # the U-turn at the far end
        else:
            x = 500.0 * k if k < 10 else 5000.0 - 500.0 * (k - 10)
            true.append(np.array([x, 0.0, 0.0 if k < 10 else math.pi]))
    T = np.array(true)
    rng = np.random.default_rng(2)
    graph = PoseGraph()
    est = [T[0]]
    for k in range(1, len(T)):
        z = between(T[k - 1], T[k]) + rng.normal(0.0, [5.0, 5.0, 0.002])
        graph.add(k - 1, k, z, sigma_info(5.0, 5.0, 0.002))
        p = est[-1]
        c, s = math.cos(p[2]), math.sin(p[2])
        est.append(np.array([p[0] + c * z[0] - s * z[1], p[1] + s * z[0] + c * z[1], p[2] + z[2]]))
    E = np.array(est)
    n = len(T)
    graph.add(0, n - 1, _hint(E[0], E[-1]), sigma_info(500.0, 500.0, math.pi), robust=True)
    out = graph.optimize(E, reject=5.0)
    assert graph.rejected == set()
    assert abs(out[-1, 2] - E[-1, 2]) < 0.01  # the heading stays where odometry has it
    assert math.hypot(*(out[-1, :2] - T[-1, :2])) <= math.hypot(*(E[-1, :2] - T[-1, :2])) + 1.0


def _wall(a, b, spacing: float, start: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``spacing`` mm along the wall from ``a`` to ``b`` (from ``start`` on), and
    their normals."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    length = float(np.hypot(*(b - a)))
    u = (b - a) / length
    t = np.arange(start, length, spacing)
    return a + t[:, None] * u, np.tile([-u[1], u[0]], (len(t), 1))


def test_a_noisy_lasers_closure_on_far_walls_is_counted_on_their_planes() -> None:
    """A hall 20 x 18 m seen from its middle: a 181-beam laser's points on walls 9-10 m away lie
    175 mm apart, the revisit's half way between the map's, and both scatter 30 mm. Placed right,
    under a third of the revisit's points are within the closure's last reach (60 mm) of a map
    point, and the closure fails its bar (0.45); nearly all lie on the walls' planes. A laser of
    10-15 mm keeps the points' share; placed 300 mm off, the planes' share is no higher."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(1)
    corners = [(-10000, -9000), (10000, -9000), (10000, 9000), (-10000, 9000)]
    walls = list(zip(corners, corners[1:] + corners[:1], strict=True))
    seen = [_wall(a, b, 175.0) for a, b in walls]
    tgt = np.concatenate([p for p, _ in seen])
    tn = np.concatenate([n for _, n in seen])
    src = np.concatenate([_wall(a, b, 175.0, 87.0)[0] for a, b in walls])
    src = src + rng.normal(0.0, 30.0, src.shape)
    tree = cKDTree(tgt)
    r = icp(
        src, tree, tgt, tn, np.array([100.0, -80.0, 0.01]), schedule=(400.0, 200.0, 100.0, 60.0)
    )
    assert r.ok and math.hypot(*r.pose[:2]) < 30.0
    assert r.inliers < 0.35
    widen = widened(23.0)  # a 30 mm laser's scatter about the walls
    assert widen > 1.0
    share = _share(r, src, tree, tgt, tn, widen)
    assert share > 0.9
    assert not _good_closure(r, False, widen)
    assert _good_closure(r, False, widen, share)
    assert _share(r, src, tree, tgt, tn, 1.0) == r.inliers
    off = dataclasses.replace(r, pose=r.pose + np.array([300.0, 300.0, 0.0]))
    assert _share(off, src, tree, tgt, tn, widen) == r.inliers
