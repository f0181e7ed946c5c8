"""``mapkit ros map-server`` checked with ROS's own tools (rostopic, rosservice) on a real sample.

One map server process serves the module; the expected grid comes from mapkit's rasteriser run
here, in the test.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import mapkit
from mapkit.raster import OccupancyGrid
from mapkit.raster.rasterize import rasterize
from mapkit.ros.grids import map_poses, served_map
from tests.ros.conftest import Ros

pytestmark = pytest.mark.ros

SAMPLE = "aria291-columbia.map"  # lines, points, goals with and without heading, home, keepout
OTHER = "aria-office.map"
RES = 0.2  # coarse, so that `rosservice call` prints a few ten thousand cells, not millions


def ros_yaml(text: str) -> Any:
    """The first document rostopic/rosservice printed."""
    return yaml.load(text.split("\n---")[0], Loader=yaml.CSafeLoader)


def echo(ros: Ros, topic: str) -> Any:
    return ros_yaml(ros.run(["rostopic", "echo", "-n1", topic], timeout=30).stdout)


@pytest.fixture(scope="module")
def sample(shared_dir: Path) -> Path:
    return shared_dir / "real" / SAMPLE


@pytest.fixture(scope="module")
def server(ros: Ros, sample: Path) -> subprocess.Popen[bytes]:
    proc = ros.start_mapkit("ros", "map-server", str(sample), "--resolution", str(RES))
    ros.wait_for(
        "the map server's services",
        lambda: proc.poll() is not None or {"/static_map", "/change_map"} <= ros.services(),
    )
    assert proc.poll() is None, ros.output(proc)
    return proc


def expected_grid(path: Path) -> Any:
    return rasterize(mapkit.load(path), RES)


def check_info(info: dict[str, Any], grid: Any) -> None:
    assert (info["width"], info["height"]) == (grid.width, grid.height)
    assert info["resolution"] == pytest.approx(RES, rel=1e-6)  # float32 on the wire
    assert info["origin"]["position"]["x"] == pytest.approx(grid.origin[0])
    assert info["origin"]["position"]["y"] == pytest.approx(grid.origin[1])
    assert info["origin"]["orientation"]["w"] == 1.0


def test_map_metadata_with_rostopic(ros: Ros, server: Any, sample: Path) -> None:
    check_info(echo(ros, "/map_metadata"), expected_grid(sample))


def test_static_map_with_rosservice(ros: Ros, server: Any, sample: Path) -> None:
    grid = expected_grid(sample)
    reply = ros_yaml(ros.run(["rosservice", "call", "/static_map"], timeout=60).stdout)["map"]
    assert reply["header"]["frame_id"] == "map"
    check_info(reply["info"], grid)
    cells = np.array(reply["data"], dtype=np.int8).reshape(grid.height, grid.width)
    assert np.array_equal(cells, grid.data)  # row 0 = south, as in ROS
    assert {-1, 0, 100} == set(np.unique(cells).tolist())


def test_map_topic_is_latched_and_matches_the_service(ros: Ros, server: Any, sample: Path) -> None:
    grid = expected_grid(sample)
    msg = echo(ros, "/map")  # a late subscriber still gets it: latched
    assert msg["header"]["frame_id"] == "map"
    assert np.array_equal(np.array(msg["data"], dtype=np.int8).reshape(grid.data.shape), grid.data)


def test_keepout_mask_and_poses(ros: Ros, server: Any, sample: Path) -> None:
    m = mapkit.load(sample)
    grid = expected_grid(sample)
    mask = echo(ros, "/keepout_mask")
    cells = np.array(mask["data"], dtype=np.int8).reshape(grid.data.shape)
    from mapkit.raster.masks import keepout_mask

    assert np.array_equal(cells, keepout_mask(m, grid).data)  # mapkit's own mask, same grid
    assert set(np.unique(cells).tolist()) == {-1, 100}
    # every forbidden area's centre and every forbidden line's middle lies in a keepout cell
    keep = grid.with_data(cells)
    for obj in m.objects:
        if obj.type == "ForbiddenArea":
            centre = np.mean(obj.corners(), axis=0)
        elif obj.type == "ForbiddenLine":
            x1, y1, x2, y2 = obj.from_to
            centre = np.array([(x1 + x2) / 2, (y1 + y2) / 2])
        else:
            continue
        assert keep.values_at([centre])[0] == 100, obj
    goals, homes, _docks = map_poses(m)
    got = echo(ros, "/map_goals")
    assert got["header"]["frame_id"] == "map"
    assert len(got["poses"]) == len(goals) == sum(o.base_type == "Goal" for o in m.objects) > 0
    for pose, msg in zip(goals, got["poses"], strict=True):
        assert msg["position"]["x"] == pytest.approx(pose.x)
        assert msg["position"]["y"] == pytest.approx(pose.y)
        yaw = 2 * math.atan2(msg["orientation"]["z"], msg["orientation"]["w"])
        assert math.isclose(math.cos(yaw - pose.yaw), 1.0, abs_tol=1e-9)
    assert len(echo(ros, "/map_homes")["poses"]) == len(homes) == 1
    info = json.loads(echo(ros, "/map_info")["data"])
    assert info["md5"] == m.md5 and info["goals"] == [g.name for g in goals]


def test_change_map_result_codes_and_republish(
    ros: Ros, server: Any, sample: Path, shared_dir: Path, tmp_path: Path
) -> None:
    def change(url: str) -> int:
        out = ros.run(["rosservice", "call", "/change_map", f"map_url: '{url}'"], timeout=60).stdout
        return int(ros_yaml(out)["result"])

    assert change(str(tmp_path / "missing.map")) == 1  # map does not exist
    bad = tmp_path / "bad.map"
    bad.write_bytes(b"2D-Map\nMinPos: 1 2 3\nDATA\n")
    assert change(str(bad)) == 2  # invalid map data
    check_info(echo(ros, "/map_metadata"), expected_grid(sample))  # still the first map

    other = shared_dir / "real" / OTHER
    assert change(f"file://{other}") == 0
    try:
        check_info(echo(ros, "/map_metadata"), expected_grid(other))  # republished
        assert json.loads(echo(ros, "/map_info")["data"])["name"] == OTHER
    finally:
        assert change(str(sample)) == 0
    check_info(echo(ros, "/map_metadata"), expected_grid(sample))


def test_change_map_to_a_map_server_yaml(
    ros: Ros, server: Any, sample: Path, tmp_path: Path
) -> None:
    from mapkit.raster.ros import write_ros_map

    def change(url: str) -> int:
        out = ros.run(["rosservice", "call", "/change_map", f"map_url: '{url}'"], timeout=60).stdout
        return int(ros_yaml(out)["result"])

    grid = expected_grid(sample).with_data(np.where(expected_grid(sample).data == 100, 100, 0))
    files = write_ros_map(grid, tmp_path / "exported.yaml")
    (tmp_path / "no_origin.yaml").write_text("image: exported.pgm\nresolution: 0.2\nnegate: 0\n")
    no_image = files.yaml.read_text().replace("exported.pgm", "gone.pgm")
    (tmp_path / "no_image.yaml").write_text(no_image)
    assert change(str(tmp_path / "no_origin.yaml")) == 3  # invalid metadata, as map_server says
    assert change(str(tmp_path / "no_image.yaml")) == 2  # the image cannot be read: invalid data
    try:
        assert change(str(files.yaml)) == 0
        msg = echo(ros, "/map")
        check_info(msg["info"], grid)
        cells = np.array(msg["data"], dtype=np.int8).reshape(grid.data.shape)
        assert np.array_equal(cells, grid.data)
    finally:
        assert change(str(sample)) == 0


def test_origin_yaw_of_a_yaml_is_published_as_map_server_does(
    ros: Ros, server: Any, sample: Path, tmp_path: Path
) -> None:
    """map_server puts the YAML's origin yaw in info.origin.orientation (setEulerZYX(yaw, 0, 0))."""
    from mapkit.raster.ros import write_ros_map

    def change(url: str) -> int:
        out = ros.run(["rosservice", "call", "/change_map", f"map_url: '{url}'"], timeout=60).stdout
        return int(ros_yaml(out)["result"])

    grid = OccupancyGrid(np.array([[0, 100, -1], [100, 0, 0]], dtype=np.int8), 0.2, (1.0, -2.0))
    files = write_ros_map(grid, tmp_path / "turned.yaml")
    yaw = 0.7
    files.yaml.write_text(
        files.yaml.read_text().replace("origin: [1.0, -2.0, 0.0]", f"origin: [1.0, -2.0, {yaw!r}]")
    )
    assert served_map(files.yaml).yaw == yaw
    try:
        assert change(str(files.yaml)) == 0
        for info in (echo(ros, "/map_metadata"), echo(ros, "/map")["info"]):
            q = info["origin"]["orientation"]
            assert (q["x"], q["y"]) == (0.0, 0.0)
            assert q["z"] == pytest.approx(math.sin(yaw / 2), abs=1e-12)
            assert q["w"] == pytest.approx(math.cos(yaw / 2), abs=1e-12)
            assert info["origin"]["position"]["x"] == pytest.approx(1.0)
        assert json.loads(echo(ros, "/map_info")["data"])["yaw"] == yaw
    finally:
        assert change(str(sample)) == 0
    assert echo(ros, "/map_metadata")["origin"]["orientation"]["w"] == 1.0


def test_served_map_refuses_bad_input_with_loadmap_codes(tmp_path: Path) -> None:
    from mapkit.ros.grids import MapLoadError

    with pytest.raises(MapLoadError, match="no such map file") as e:
        served_map(tmp_path / "nope.map")
    assert e.value.code == 1
    (tmp_path / "bad.map").write_bytes(b"2D-Map\nMinPos: x\n")
    with pytest.raises(MapLoadError, match=r"bad\.map:2") as e:
        served_map(tmp_path / "bad.map")
    assert e.value.code == 2
    os.mkfifo(tmp_path / "pipe.yaml")  # refused at once, not read (a read would block)
    with pytest.raises(MapLoadError, match="not a regular file") as e:
        served_map(tmp_path / "pipe.yaml")
    assert e.value.code == 1
    with pytest.raises(MapLoadError, match="not a valid file name"):
        served_map(str(tmp_path / "nul\0.yaml"))
    (tmp_path / "ok.map").write_bytes(b"2D-Map\nDATA\n0 0\n")
    with pytest.raises(MapLoadError, match="resolution must be a positive") as e:
        served_map(tmp_path / "ok.map", resolution=0)
    assert e.value.code == 3


def test_map_server_without_a_master_fails_cleanly(ros: Ros, sample: Path) -> None:
    from tests.ros.conftest import free_port

    env = dict(ros.env, ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}")
    res = ros.mapkit("ros", "map-server", str(sample), check=False, env=env, timeout=30)
    assert res.returncode == 1
    assert "no ROS master answers at http://127.0.0.1:" in res.stderr
    res = ros.mapkit("ros", "map-server", "/nonexistent/x.map", check=False, timeout=30)
    assert res.returncode == 2 and "cannot read /nonexistent/x.map: no such file" in res.stderr
