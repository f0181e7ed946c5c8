"""Tests of mapkit.build._match's geometry helpers (ICP itself: test_fast_paths, test_build)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings, strategies as st

from mapkit.build._match import local_planes


@settings(max_examples=40, deadline=None)
@given(
    angle=st.floats(0.0, math.pi),
    noise=st.floats(1.0, 10.0),
    flip=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_local_planes_pull_a_noisy_wall_onto_its_line(
    angle: float, noise: float, flip: bool, seed: int
) -> None:
    """Points scattered about a wall (several scans' range noise) come back nearer its line, with
    normals across it that face as the points' own did."""
    rng = np.random.default_rng(seed)
    along = np.array([math.cos(angle), math.sin(angle)])
    across = np.array([-along[1], along[0]])
    t = np.sort(rng.uniform(0.0, 4000.0, 200))
    off = rng.normal(0.0, noise, len(t))
    pts = 500.0 + t[:, None] * along + off[:, None] * across
    facing = -across if flip else across
    planes, normals = local_planes(pts, np.tile(facing, (len(pts), 1)), m=8)
    assert planes.shape == pts.shape and normals.shape == pts.shape
    before = np.sqrt(np.mean(off**2))
    after = np.sqrt(np.mean(((planes - 500.0) @ across) ** 2))
    assert after < 0.6 * before, (after, before)
    np.testing.assert_allclose(np.hypot(normals[:, 0], normals[:, 1]), 1.0)
    facing_dot = normals @ facing
    assert np.all(facing_dot > 0.0)
    assert np.median(facing_dot) > math.cos(math.radians(5.0))


def test_fewer_points_than_a_plane_needs_come_back_as_they_are() -> None:
    pts = np.array([[0.0, 0.0], [10.0, 1.0], [20.0, -1.0]])
    nrm = np.tile([0.0, 1.0], (3, 1))
    planes, normals = local_planes(pts, nrm, m=8)
    np.testing.assert_array_equal(planes, pts)
    np.testing.assert_array_equal(normals, nrm)
