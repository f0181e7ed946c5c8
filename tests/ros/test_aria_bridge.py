"""``mapkit ros aria-bridge``: ARIA 2.9.1's own server -> mapkit -> a real roscore, checked with
ROS's own ``rostopic``; the robot's map is switched with ARIA's own client (``run-probe``)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mapkit
from mapkit.raster.masks import keepout_mask
from mapkit.raster.rasterize import rasterize
from mapkit.ros.grids import map_poses
from tests.arnet.peer import Peer, start_peer
from tests.ros.conftest import Ros
from tests.ros.test_map_server import RES, echo

pytestmark = pytest.mark.ros

FIRST, SECOND = "aria291-columbia.map", "aria-office.map"


@pytest.fixture(scope="module")
def peer(tmp_path_factory: pytest.TempPathFactory, shared_dir: Path) -> Iterator[Peer]:
    maps = [shared_dir / "real" / FIRST, shared_dir / "real" / SECOND]
    p = start_peer(tmp_path_factory.mktemp("peer"), maps, active=FIRST)
    yield p
    p.stop()


@pytest.fixture(scope="module")
def bridge(ros: Ros, peer: Peer) -> Any:
    proc = ros.start_mapkit(
        "ros",
        "aria-bridge",
        peer.address,
        "-u",
        "admin",
        "--resolution",
        str(RES),
        "--json",
        env=dict(ros.env, MAPKIT_ARIA_PASSWORD="secret1"),
    )
    ros.wait_for(
        "the bridge's static_map service",
        lambda: proc.poll() is not None or "/static_map" in ros.services(),
    )
    assert proc.poll() is None, ros.output(proc)
    return proc


def map_info(ros: Ros) -> dict[str, Any]:
    return dict(json.loads(echo(ros, "/map_info")["data"]))


def check_served(ros: Ros, path: Path) -> None:
    m = mapkit.load(path)
    grid = rasterize(m, RES)
    info = map_info(ros)
    assert info["name"] == path.name and info["md5"] == m.md5
    assert (info["width"], info["height"]) == (grid.width, grid.height)
    msg = echo(ros, "/map")
    assert np.array_equal(np.array(msg["data"], dtype=np.int8).reshape(grid.data.shape), grid.data)
    goals = echo(ros, "/map_goals")["poses"]
    assert len(goals) == len(map_poses(m)[0])
    if info["keepout"]:
        mask = np.array(echo(ros, "/keepout_mask")["data"], dtype=np.int8)
        assert np.array_equal(mask.reshape(grid.data.shape), keepout_mask(m, grid).data)


def test_bridge_serves_the_robots_map_and_follows_changes(
    ros: Ros, peer: Peer, bridge: Any
) -> None:
    check_served(ros, peer.root / FIRST)
    assert "/change_map" not in ros.services()  # the robot decides which map is active
    assert map_info(ros)["keepout"]  # columbia has forbidden areas and lines
    res = peer.probe("setmap", SECOND, "5")
    assert "save succeeded" in res.stdout, res.stdout
    ros.wait_for("the bridge to republish", lambda: map_info(ros)["name"] == SECOND, timeout=60)
    check_served(ros, peer.root / SECOND)
    lines = [json.loads(x) for x in ros.output(bridge).splitlines() if x.startswith("{")]
    assert [x["robot_map"] for x in lines] == [FIRST, SECOND]
    assert ros.stop(bridge) == 0
    assert "Traceback" not in ros.output(bridge)
