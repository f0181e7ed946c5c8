"""The ROS 2 messages as CDR bytes: round trips through rosbags' deserialiser, discovery data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st

from mapkit.raster.grid import OccupancyGrid
from mapkit.ros.grids import Pose
from mapkit.ros2.errors import Ros2Error
from mapkit.ros2.graph import dds_topic, endpoint_user_data, participant_user_data, resolve_topic
from mapkit.ros2.messages import (
    COSTMAP_FILTER_INFO,
    OCCUPANCY_GRID,
    PARTICIPANT_ENTITIES_INFO,
    POSE_ARRAY,
    costmap_filter_info_cdr,
    grid_cdr,
    participant_entities_info_cdr,
    pose_array_cdr,
    type_hash,
    typestore,
)

finite = st.floats(-1e4, 1e4, allow_nan=False)
grids = st.builds(
    lambda w, h, seed, res, ox, oy: OccupancyGrid(
        np.random.default_rng(seed).choice(np.array([-1, 0, 100, 37], np.int8), (h, w)),
        res,
        (ox, oy),
    ),
    st.integers(1, 40),
    st.integers(1, 40),
    st.integers(0, 2**32),
    st.floats(0.001, 10),
    finite,
    finite,
)


@given(
    grids,
    st.floats(0, 2e9),
    st.sampled_from(["humble", "jazzy"]),
    st.text(st.characters(min_codepoint=32, max_codepoint=126), max_size=20),
)
def test_grid_round_trips(grid: OccupancyGrid, stamp: float, distro: str, frame: str) -> None:
    raw = grid_cdr(grid, frame, stamp, distro=distro)
    assert raw[:4] == b"\x00\x01\x00\x00"  # CDR little-endian: XCDR1 as rmw writes it
    msg = typestore(distro).deserialize_cdr(raw, OCCUPANCY_GRID)
    assert msg.header.frame_id == frame
    assert abs(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - stamp) < 1e-6
    assert msg.info.map_load_time == msg.header.stamp
    assert (msg.info.width, msg.info.height) == (grid.width, grid.height)
    assert msg.info.resolution == np.float32(grid.resolution)
    assert (msg.info.origin.position.x, msg.info.origin.position.y) == grid.origin
    assert msg.info.origin.orientation.w == 1.0
    assert np.array_equal(np.asarray(msg.data, np.int8).reshape(grid.height, grid.width), grid.data)


@given(st.lists(st.builds(Pose, finite, finite, st.floats(-math.pi, math.pi)), max_size=8))
def test_pose_array_round_trips(poses: list[Pose]) -> None:
    msg = typestore().deserialize_cdr(pose_array_cdr(tuple(poses), "map", 5.0), POSE_ARRAY)
    assert len(msg.poses) == len(poses)
    for got, p in zip(msg.poses, poses, strict=False):
        assert (got.position.x, got.position.y, got.position.z) == (p.x, p.y, 0.0)
        assert math.isclose(
            2 * math.atan2(got.orientation.z, got.orientation.w), p.yaw, abs_tol=1e-9
        )


def test_costmap_filter_info_is_a_keepout_filter() -> None:
    msg = typestore().deserialize_cdr(
        costmap_filter_info_cdr("/keepout_filter_mask"), COSTMAP_FILTER_INFO
    )
    assert (msg.type, msg.filter_mask_topic, msg.base, msg.multiplier) == (
        0,
        "/keepout_filter_mask",
        0.0,
        1.0,
    )


@pytest.mark.parametrize(("distro", "size"), [("humble", 24), ("jazzy", 16)])
def test_discovery_info_gid_layout(distro: str, size: int) -> None:
    guid, writer = bytes(range(16)), bytes(range(16, 32))
    raw = participant_entities_info_cdr(guid, "map_server", "/", [writer], distro=distro)
    msg = typestore(distro).deserialize_cdr(raw, PARTICIPANT_ENTITIES_INFO)
    assert bytes(msg.gid.data) == guid.ljust(size, b"\0")
    node = msg.node_entities_info_seq[0]
    assert (node.node_name, node.node_namespace) == ("map_server", "/")
    assert [bytes(g.data) for g in node.writer_gid_seq] == [writer.ljust(size, b"\0")]
    with pytest.raises(Ros2Error, match="16 bytes"):
        participant_entities_info_cdr(b"short", "n", "/", [], distro=distro)


def test_type_hashes_and_user_data() -> None:
    h = type_hash(OCCUPANCY_GRID)
    assert h.startswith("RIHS01_") and len(h) == 7 + 64
    assert type_hash(COSTMAP_FILTER_INFO) != h
    assert endpoint_user_data(h) == f"typehash={h};".encode()
    assert endpoint_user_data(None) == b""
    assert participant_user_data() == b"enclave=/;"
    with pytest.raises(Ros2Error, match="unknown ROS 2 distribution"):
        typestore("rolling")


@pytest.mark.parametrize("bad", ["", "~/map", "a//b", "1map", "map-x", "/m\u00e4p"])
def test_bad_topic_names_are_refused(bad: str) -> None:
    with pytest.raises(Ros2Error):
        dds_topic(bad)
    assert resolve_topic("map", "/robot1/") == "/robot1/map"
