"""``mapkit ros2 aria-bridge``: ARIA 2.9.1's own ArNetworking server -> mapkit -> DDS readers
(Fast DDS as rmw_fastrtps, Cyclone as rmw_cyclonedds); the robot's map is switched with ARIA's
own client and the change reaches the readers."""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from mapkit.ros.grids import served_map
from tests.arnet.peer import Peer, start_peer
from tests.ros2.netns import NetNs
from tests.ros2.relay import serve_unix
from tests.ros2.test_peers import PEERS, check_grid, check_poses, finish, start, wait_line

pytestmark = [pytest.mark.network, pytest.mark.slow]
FIRST, SECOND = "aria291-columbia.map", "aria-office.map"


@pytest.fixture
def robot(tmp_path: Path, shared_dir: Path) -> Iterator[Peer]:
    p = start_peer(
        tmp_path / "peer", [shared_dir / "real" / FIRST, shared_dir / "real" / SECOND], active=FIRST
    )
    yield p
    p.stop()


def test_bridge_publishes_the_robots_map_and_follows_a_switch(
    peers: dict[str, Path], netns: NetNs, robot: Peer, tmp_path: Path
) -> None:
    sock = str(tmp_path / "robot.sock")
    unix = serve_unix(sock, robot.port)
    relay = start(netns, [sys.executable, "-m", "tests.ros2.relay", sock])
    bridge = None
    try:
        assert relay.stdout is not None
        port = relay.stdout.readline().strip()
        bridge = start(
            netns,
            [
                sys.executable,
                "-m",
                "mapkit",
                "ros2",
                "aria-bridge",
                f"127.0.0.1:{port}",
                "-u",
                "admin",
                "--domain",
                "13",
                "--json",
            ],
            env_extra={"MAPKIT_ARIA_PASSWORD": "secret1"},
        )
        first = json.loads(wait_line(bridge, "{"))
        assert first["robot_map"] == FIRST and first["keepout"]
        readers: dict[str, Any] = {}
        early: dict[str, list[str]] = {}
        for name in PEERS:
            (tmp_path / name).mkdir()
            readers[name] = start(
                netns,
                [
                    str(peers[name]),
                    "13",
                    str(tmp_path / name),
                    "90",
                    "grid:rt/map:2",
                    "poses:rt/map_goals:2",
                ],
            )
            early[name] = []
            wait_line(readers[name], "grid ", early[name])
        res = robot.probe("setmap", SECOND, "5")
        assert "save succeeded" in res.stdout, res.stdout
        second = json.loads(wait_line(bridge, "{"))
        assert second["robot_map"] == SECOND
        old, new = served_map(robot.root / FIRST), served_map(robot.root / SECOND)
        assert old.goals and old.goals != new.goals
        for name, proc in readers.items():
            lines = early[name] + finish(proc, timeout=90)
            grids = [ln for ln in lines if ln.startswith("grid ")]
            check_grid(grids[0], tmp_path / name, old.grid)
            check_grid(grids[1], tmp_path / name, new.grid)
            goals = [ln for ln in lines if ln.startswith("poses ")]
            check_poses(goals[0], old.goals)
            check_poses(goals[1], new.goals)
    finally:
        for proc in (bridge, relay):
            if proc is not None:
                proc.terminate()
                proc.communicate(timeout=20)
        unix.close()
