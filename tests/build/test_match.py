"""Tests of mapkit.build._match's geometry helpers (ICP itself: test_fast_paths, test_build)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from mapkit.build._match import local_planes, surface_noise


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


@settings(max_examples=30, deadline=None)
@given(
    st.floats(3000.0, 12000.0),
    st.sampled_from([181, 361, 683]),
    st.floats(3.0, 40.0),
    st.integers(0, 2**31 - 1),
)
def test_the_lasers_noise_is_read_off_its_scans(
    radius: float, beams: int, noise: float, seed: int
) -> None:
    """Scans of a round room from its centre (every beam meets the wall square on, so all of
    its range noise lies across the wall): the scatter read off them is the noise, within 15 %,
    however dense the beams (the 683 of a URG are closer than its noise at a metre)."""
    rng = np.random.default_rng(seed)
    a = np.radians(np.linspace(-90.0, 90.0, beams))
    scans = []
    for _ in range(20):
        r = radius + rng.normal(0.0, noise, beams)
        scans.append(np.column_stack([r * np.cos(a), r * np.sin(a)]))
    assert surface_noise(scans) == pytest.approx(noise, rel=0.15)


def test_corners_and_gaps_do_not_count_as_noise() -> None:
    """A noiseless square room and a scan with a doorway: none of its points scatter."""
    a = np.radians(np.linspace(-135.0, 135.0, 541))
    # The room's walls 4 m away: the range to a square's side along each beam.
    r = 4000.0 / np.maximum(np.abs(np.cos(a)), np.abs(np.sin(a)))
    r[200:230] += 3000.0  # through a doorway, a far wall
    pts = np.column_stack([r * np.cos(a), r * np.sin(a)])
    assert surface_noise([pts] * 5) < 0.5
    assert surface_noise([]) == 0.0
