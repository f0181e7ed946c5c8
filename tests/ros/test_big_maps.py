"""Big maps on the map server: ROS 1's message limit said before the work, packed serialisation."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mapkit
from mapkit.raster.rasterize import rasterize
from mapkit.ros.grids import (
    LOAD_INVALID_DATA,
    ROS1_MAX_CELLS,
    MapLoadError,
    check_ros1_size,
    grid_message,
    packed_response,
    served_map,
)
from tests.ros.conftest import require_ros

ROOT = Path(__file__).resolve().parents[2]


def test_a_grid_over_ros1s_limit_is_refused_before_any_work(tmp_path: Path) -> None:
    # 1 km x 1 km at 2 cm: 2.5 G cells. Refused at once (its geometry takes no memory).
    big = tmp_path / "campus.map"
    big.write_bytes(b"2D-Map\nDATA\n0 0\n1000000 1000000\n")
    with pytest.raises(MapLoadError, match=r"campus\.map: a 50051 x 50051 grid .* roscpp") as e:
        served_map(big, resolution=0.02)
    assert e.value.code == LOAD_INVALID_DATA
    assert "1,000,000,000 bytes" in str(e.value)
    # A map_server image whose header says 40000 x 30000: refused from the header alone.
    (tmp_path / "huge.pgm").write_bytes(b"P5\n# header only\n40000 30000\n255\n")
    (tmp_path / "huge.yaml").write_text(
        "image: huge.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    with pytest.raises(MapLoadError, match=r"huge\.pgm: a 40000 x 30000 grid") as e:
        served_map(tmp_path / "huge.yaml")
    assert e.value.code == LOAD_INVALID_DATA
    check_ros1_size(20_768, 13_612)  # the 415 x 270 m site at 2 cm: 282 M cells, fine
    with pytest.raises(MapLoadError):
        check_ros1_size(ROS1_MAX_CELLS + 1, 1)


@pytest.fixture
def ros_msgs() -> None:
    require_ros()


def test_packed_messages_are_the_bytes_rospy_writes(ros_msgs: None) -> None:
    from nav_msgs.msg import OccupancyGrid
    from nav_msgs.srv import GetMapResponse, LoadMapResponse

    m = mapkit.load(ROOT / "mapkit" / "sample_maps" / "office.map")
    grid = rasterize(m, 0.1)
    packed = grid_message(grid, "map")
    plain = OccupancyGrid()
    plain.header.frame_id = "map"
    plain.info = packed.info
    plain.data = grid.data.ravel().tolist()

    def wire(msg: object) -> bytes:
        buf = io.BytesIO()
        msg.serialize(buf)  # type: ignore[attr-defined]
        return buf.getvalue()

    assert packed.data == [] and wire(packed) == wire(plain)
    assert wire(packed_response("GetMap", packed)) == wire(GetMapResponse(map=plain))
    assert wire(packed_response("LoadMap", packed, result=0)) == wire(
        LoadMapResponse(map=plain, result=0)
    )
    back = OccupancyGrid()
    back.deserialize(wire(packed))
    assert np.array_equal(np.array(back.data, dtype=np.int8).reshape(grid.data.shape), grid.data)


_BIG = """
import io, json, sys
from pathlib import Path
from mapkit import MapData, MapObject, Scan, save
from mapkit.ros.grids import grid_message, packed_response, served_map

def peak_kb():
    with open("/proc/self/status") as fh:
        return next(int(l.split()[1]) for l in fh if l.startswith("VmHWM:"))

walls = [[0, 0, 100000, 0], [100000, 0, 100000, 100000], [100000, 100000, 0, 100000],
         [0, 100000, 0, 0]]
m = MapData(scans=(Scan.from_arrays(lines=walls),),
            objects=(MapObject("RobotHome", 10000, 10000),
                     MapObject("ForbiddenArea", 0, 0, 0, from_to=(60000, 60000, 70000, 65000))))
path = Path(sys.argv[1]) / "hall.map"
save(m, path)
served = served_map(path, 0.01, margin_m=0.05)
msg = grid_message(served.grid)
buf = io.BytesIO()
packed_response("GetMap", msg).serialize(buf)
g = served.grid
print(json.dumps({"cells": g.width * g.height, "bytes": len(buf.getvalue()),
                  "keepout": int((served.keepout.data == 100).sum()), "peak_kb": peak_kb()}))
"""


def test_a_100m_cell_map_is_served_in_about_its_own_size(ros_msgs: None, tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-c", _BIG, str(tmp_path)],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    )
    r = json.loads(out.stdout)
    assert r["cells"] > 100_000_000 and r["bytes"] > r["cells"]
    assert 500_000 <= r["keepout"] <= 505_000
    # grid + keepout + the serialised copy: about 3 bytes a cell. rospy's own int8[] path holds a
    # Python list (8 bytes a cell) and the tuple struct.pack(*list) makes (8 more): over 1.6 GB.
    assert r["peak_kb"] < 700_000, r  # measured: about 510 MB


def test_a_map_server_pgm_is_read_by_bands(tmp_path: Path) -> None:
    from mapkit.raster.ros import read_ros_map, write_ros_map

    grid = rasterize(mapkit.load(ROOT / "mapkit" / "sample_maps" / "office.map"), 0.05)
    files = write_ros_map(grid, tmp_path / "office.yaml")
    served = served_map(files.yaml)
    assert served.grid == read_ros_map(files.yaml) == grid and served.keepout is None
    assert not served.grid.data.flags.writeable
    files.image.write_bytes(files.image.read_bytes()[:-100])
    with pytest.raises(MapLoadError, match="truncated") as e:
        served_map(files.yaml)
    assert e.value.code == LOAD_INVALID_DATA
