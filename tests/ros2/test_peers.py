"""mapkit's ROS 2 topics reach two independent DDS readers that subscribe as ROS 2 does.

The readers (tests/ros2/peers) are a C++ program on Fast DDS (as rmw_fastrtps, ROS 2's
default) and a C program on Cyclone DDS (as rmw_cyclonedds), built from Debian's packages. Each
joins after the map is published and must get it (transient-local, as nav2's /map). Everything
runs in a private network namespace.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mapkit.raster.grid import OccupancyGrid
from mapkit.ros.grids import Pose, served_map
from tests.conftest import ROOT, SHARED
from tests.ros2.netns import NetNs

pytestmark = [pytest.mark.network, pytest.mark.slow]
REAL = sorted((SHARED / "sample-data" / "real").glob("*.map"))
PEERS = ("fastdds", "cyclone")


def start(
    ns: NetNs, cmd: list[str], env_extra: dict[str, str] | None = None
) -> subprocess.Popen[str]:
    """Start ``cmd`` inside the namespace (pipes for stdin, stdout, stderr)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), **(env_extra or {}))
    return subprocess.Popen(
        ns.wrap(cmd),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.PIPE,
        text=True,
        env=env,
        cwd=ROOT,
    )


def wait_line(proc: subprocess.Popen[str], prefix: str, seen: list[str] | None = None) -> str:
    """The first line of ``proc`` starting with ``prefix``; lines read are added to ``seen``."""
    assert proc.stdout is not None
    for line in proc.stdout:
        if seen is not None:
            seen.append(line.rstrip("\n"))
        if line.startswith(prefix):
            return line
    raise AssertionError(f"process ended before {prefix!r}: {proc.stderr.read()}")  # type: ignore[union-attr]


def finish(proc: subprocess.Popen[str], timeout: float = 60) -> list[str]:
    out, errs = proc.communicate(timeout=timeout)
    assert proc.returncode == 0, f"reader failed ({proc.returncode}): {errs}"
    return out.splitlines()


def check_grid(line: str, outdir: Path, grid: OccupancyGrid, frame: str = "map") -> None:
    f = line.split()
    spec, n = f[1], f[2]
    sec, nsec, frame_id, lsec, lnsec = int(f[3]), int(f[4]), f[5], int(f[6]), int(f[7])
    res, width, height = float(f[8]), int(f[9]), int(f[10])
    origin, length = [float(v) for v in f[11:18]], int(f[18])
    assert frame_id == frame
    assert (lsec, lnsec) == (sec, nsec) and abs(sec - time.time()) < 600
    assert np.float32(res) == np.float32(grid.resolution)  # %.9g round-trips a float32
    assert (width, height) == (grid.width, grid.height)
    assert origin == [grid.origin[0], grid.origin[1], 0, 0, 0, 0, 1]
    cells = np.fromfile(outdir / f"{spec}.{n}.bin", dtype=np.int8)
    assert length == cells.size == grid.width * grid.height
    assert np.array_equal(cells.reshape(grid.height, grid.width), grid.data)


def check_poses(line: str, poses: tuple[Pose, ...]) -> None:
    f = line.split()
    assert f[5] == "map" and int(f[6]) == len(poses)
    values = [float(v) for v in f[7 : 7 + 7 * len(poses)]]
    for k, p in enumerate(poses):
        x, y, z, qx, qy, qz, qw = values[7 * k : 7 * k + 7]
        assert (x, y, z, qx, qy) == (p.x, p.y, 0, 0, 0)
        assert (qz, qw) == (math.sin(p.yaw / 2), math.cos(p.yaw / 2))


def by_spec(lines: list[str], kind: str) -> dict[int, list[str]]:
    out: dict[int, list[str]] = {}
    for line in lines:
        if line.startswith(kind + " "):
            out.setdefault(int(line.split()[1]), []).append(line)
    return out


@pytest.mark.skipif(not REAL, reason="no real maps in ../shared")
def test_late_readers_get_every_real_map_mask_and_goals(
    peers: dict[str, Path], netns: NetNs, tmp_path: Path
) -> None:
    served = [served_map(p) for p in REAL]
    pub = start(netns, [sys.executable, "-m", "tests.ros2.publish_maps", "7", *map(str, REAL)])
    try:
        wait_line(pub, "PUBLISHED")
        specs = []
        for i in range(len(REAL)):  # spec index 4i: grid, 4i+1: mask, 4i+2: info, 4i+3: goals
            specs += [
                f"grid:rt/map_{i}:1",
                f"grid:rt/keepout_{i}:1",
                f"info:rt/filter_info_{i}:1",
                f"poses:rt/goals_{i}:1",
            ]
        readers = {}
        for name in PEERS:  # both join late, side by side
            (tmp_path / name).mkdir()
            readers[name] = start(
                netns, [str(peers[name]), "7", str(tmp_path / name), "60", *specs]
            )
        for name, proc in readers.items():
            lines = finish(proc)
            grids, infos, poses = (
                by_spec(lines, "grid"),
                by_spec(lines, "info"),
                by_spec(lines, "poses"),
            )
            for i, s in enumerate(served):
                check_grid(grids[4 * i][0], tmp_path / name, s.grid)
                assert s.keepout is not None
                check_grid(grids[4 * i + 1][0], tmp_path / name, s.keepout)
                f = infos[4 * i + 2][0].split()
                assert (f[5], f[6], f[7], f[8], f[9]) == ("map", "0", f"/keepout_{i}", "0", "1")
                check_poses(poses[4 * i + 3][0], s.goals)
    finally:
        pub.stdin.close()  # type: ignore[union-attr]
        pub.wait(timeout=20)


@pytest.mark.skipif(len(REAL) < 2, reason="needs two real maps in ../shared")
def test_a_map_changed_on_disk_reaches_running_readers(
    peers: dict[str, Path], netns: NetNs, tmp_path: Path
) -> None:
    """The real CLI serves a file; readers that joined late get the map, a broken rewrite
    changes nothing, and the next good version reaches them."""
    first, second = REAL[0], REAL[-1]
    path = tmp_path / "served.map"
    shutil.copyfile(first, path)
    server = start(
        netns,
        [
            sys.executable,
            "-m",
            "mapkit",
            "ros2",
            "map-server",
            str(path),
            "--domain",
            "9",
            "--frame",
            "world",
            "--json",
        ],
    )
    try:
        wait_line(server, "{")
        readers = {}
        for name in PEERS:
            (tmp_path / name).mkdir()
            readers[name] = start(
                netns, [str(peers[name]), "9", str(tmp_path / name), "60", "grid:rt/map:2"]
            )
            wait_line(readers[name], "grid ")
        path.write_text("2D-Map\nnot a map at all\x00\n", encoding="latin-1")
        time.sleep(1.5)  # the server polls twice a second: it sees the broken file and keeps on
        tmp = tmp_path / "new.map"
        shutil.copyfile(second, tmp)
        os.replace(tmp, path)
        for name, proc in readers.items():
            lines = [ln for ln in finish(proc) if ln.startswith("grid ")]
            assert len(lines) == 1  # the first line was read by wait_line
            check_grid(lines[0], tmp_path / name, served_map(second).grid, frame="world")
            check_grid_first = served_map(first).grid
            assert np.array_equal(
                np.fromfile(tmp_path / name / "0.1.bin", dtype=np.int8).reshape(
                    check_grid_first.height, check_grid_first.width
                ),
                check_grid_first.data,
            )
    finally:
        server.terminate()
        _out, errs = server.communicate(timeout=20)
    assert "still serving the previous map" in errs
    assert server.returncode == 0 and "Traceback" not in errs, errs


def test_discovery_data_is_what_ros2_writes(
    peers: dict[str, Path], netns: NetNs, tmp_path: Path
) -> None:
    """From DDS's built-in topics and ros_discovery_info, as a ROS 2 graph cache sees them:
    enclave user data, Jazzy type hashes on every writer, the node listing its writers."""
    from mapkit.ros2.messages import COSTMAP_FILTER_INFO, OCCUPANCY_GRID, POSE_ARRAY, type_hash

    server = start(
        netns,
        [
            sys.executable,
            "-m",
            "mapkit",
            "ros2",
            "map-server",
            str(REAL[0]),
            "--domain",
            "5",
            "--json",
        ],
    )
    try:
        wait_line(server, "{")
        reader = start(
            netns,
            [
                str(peers["cyclone"]),
                "5",
                str(tmp_path),
                "30",
                "entities:ros_discovery_info:1",
                "graph:rt/:6",
            ],
        )
        lines = finish(reader)
    finally:
        server.terminate()
        server.communicate(timeout=20)
    writers = {f[5]: f for f in (ln.split() for ln in lines if ln.startswith("writer "))}
    types = {
        "rt/map": OCCUPANCY_GRID,
        "rt/keepout_filter_mask": OCCUPANCY_GRID,
        "rt/costmap_filter_info": COSTMAP_FILTER_INFO,
        "rt/map_goals": POSE_ARRAY,
        "rt/map_homes": POSE_ARRAY,
        "rt/map_docks": POSE_ARRAY,
    }
    assert set(writers) == set(types)
    for topic, typename in types.items():
        f = writers[topic]
        pkg, kind, name = typename.split("/")
        assert f[6] == f"{pkg}::{kind}::dds_::{name}_"
        assert f[7] == f"typehash={type_hash(typename)};"
    participant = {f[4] for f in writers.values()}
    assert len(participant) == 1
    (guid,) = participant
    assert f"participant {guid} enclave=/;" in lines
    (entities,) = [ln.split() for ln in lines if ln.startswith("entities ")]
    assert entities[3] == guid
    assert entities[4:8] == ["node", "/", "mapkit_map_server", "6"]
    assert set(entities[8:]) == {f[3] for f in writers.values()}
