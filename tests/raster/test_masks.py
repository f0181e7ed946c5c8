"""Nav2 keepout and speed masks and the costmap filter parameters file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import mapkit
from mapkit.model import MapData, MapObject, Scan
from mapkit.raster import RasterError, burn_polygons, object_polygons, rasterize
from mapkit.raster.masks import (
    filter_params_text,
    keepout_mask,
    speed_mask,
    speed_zones,
    write_filters,
)
from mapkit.raster.ros import read_ros_map

from .rosloader import cells, decode

MOVEMENT_INFO = [
    ("SectorType", "Name=MovementParametersSector", '"Label=MovementParameters"'),
    (
        "ArgDesc",
        "Name=Importance",
        "Parent=MovementParametersSector",
        "Type=string",
        "Value=Normal",
    ),
    ("ArgDesc", "Name=TransVelMax", "Parent=MovementParametersSector", "Type=int", "Value=0"),
    ("ArgDesc", "Name=RotVelMax", "Parent=MovementParametersSector", "Type=int", "Value=0"),
    ("SectorType", "Name=SlowSector"),
    ("ArgDesc", '"Name=MaxSpeed"', '"Parent=SlowSector"', '"Value=300"'),
]


def _speed_map() -> MapData:
    walls = [[0, 0, 10000, 0], [10000, 0, 10000, 8000], [10000, 8000, 0, 8000], [0, 8000, 0, 0]]
    objects = (
        MapObject("RobotHome", 500, 500),
        MapObject(
            "MovementParametersSector", 0, 0, 0, name="Slow hall", from_to=(1000, 1000, 4000, 3000)
        ),
        MapObject(
            "MovementParametersSector",
            0,
            0,
            0,
            name="Slower corner",
            from_to=(3000, 2000, 5000, 4000),
        ),
        MapObject(
            "MovementParametersSector", 0, 0, 0, name="Default", from_to=(6000, 1000, 7000, 2000)
        ),
        MapObject("SlowSector", 0, 0, 45, name="Diag", from_to=(8339, -2268, 9339, -1268)),
        MapObject("ForbiddenArea", 0, 0, 0, from_to=(8000, 6000, 9000, 7000)),
    )
    info = {
        "MapInfo": MOVEMENT_INFO,
        "CairnInfo": [
            ("Params", '"Slow hall"', "Normal", "500", "0"),
            ("Params", '"Slower corner"', '"Most Important"', "250", "0"),
            ("Params", '"Default"', "Normal", "0", "0"),
        ],
    }
    return MapData(
        category="2D-Map-Ex2", scans=(Scan.from_arrays(lines=walls),), objects=objects, info=info
    )


def test_speed_zones_read_params_and_defaults() -> None:
    zones = speed_zones(_speed_map())
    assert [(z.name, z.speed_mm_s) for z in zones] == [
        ("Slow hall", 500.0),
        ("Slower corner", 250.0),
        ("Diag", 300.0),
    ]
    assert speed_zones(_speed_map(), param="RotVelMax") == []


def test_speed_mask_values_and_overlap() -> None:
    m = _speed_map()
    g = rasterize(m, 0.1)
    mask, mult = speed_mask(m, g)
    assert mult == 0.01 and mask.same_geometry(g)
    assert mask.values_at(
        [
            [2000, 1500],
            [3500, 2500],
            [4500, 3500],
            [6500, 1500],
            [500, 500],
            [7500, 5000],
            [8100, 5600],
        ]
    ).tolist() == [50, 25, 25, 0, 0, 30, 0]
    assert -1 not in mask.data  # unknown is an error for Nav2's speed filter
    fast, mult = speed_mask(m, g, multiplier=0.1)
    assert mult == 0.1 and fast.values_at([[2000, 1500]]).tolist() == [5]
    with pytest.raises(RasterError, match="positive"):
        speed_mask(m, g, multiplier=0)


def test_keepout_mask_is_unknown_outside_the_zones() -> None:
    m = _speed_map()
    g = rasterize(m, 0.1)
    mask = keepout_mask(m, g)
    assert mask.same_geometry(g)
    zone = burn_polygons(g, object_polygons([m.objects[-1]]))
    assert np.array_equal(mask.data == 100, zone)
    assert (mask.data[~zone] == -1).all()
    grown = keepout_mask(m, g, inflate_mm=300)
    assert (grown.data == 100).sum() > zone.sum()


def test_write_filters_files_load_as_masks(tmp_path: Path) -> None:
    m = _speed_map()
    g = rasterize(m, 0.05)
    files = write_filters(m, g, tmp_path / "office.yaml", speed=True)
    assert files.keepout_yaml == tmp_path / "office_keepout.yaml"
    assert files.keepout_image == tmp_path / "office_keepout.pgm"
    assert files.speed_yaml == tmp_path / "office_speed.yaml"
    assert files.params == tmp_path / "office_filters.yaml"
    assert (files.keepout_zones, files.speed_zones, files.speed_multiplier) == (1, 3, 0.01)
    keep, kdoc = cells(files.keepout_yaml)
    assert kdoc["mode"] == "trinary" and np.array_equal(keep, keepout_mask(m, g).data)
    assert set(np.unique(decode(files.keepout_image)[0])) == {0, 205}
    speed, sdoc = cells(files.speed_yaml)
    assert sdoc["mode"] == "raw" and np.array_equal(speed, speed_mask(m, g)[0].data)
    assert read_ros_map(files.speed_yaml, flavor="nav2") == speed_mask(m, g)[0]
    # Both masks are on the map's grid.
    assert kdoc["origin"][:2] == list(g.origin) and kdoc["resolution"] == g.resolution


def test_params_file_runs_as_nav2_expects(tmp_path: Path) -> None:
    m = _speed_map()
    g = rasterize(m, 0.05)
    files = write_filters(m, g, tmp_path / "site.yaml", speed=True, speed_multiplier=0.02)
    text = files.params.read_text()
    doc = yaml.safe_load(text)
    ko = doc["keepout_filter_mask_server"]["ros__parameters"]
    assert Path(ko["yaml_filename"]).is_absolute() and Path(ko["yaml_filename"]).exists()
    assert ko["topic_name"] == "/keepout_filter_mask" and ko["frame_id"] == "map"
    ki = doc["keepout_costmap_filter_info_server"]["ros__parameters"]
    assert ki == {
        "type": 0,
        "filter_info_topic": "/keepout_costmap_filter_info",
        "mask_topic": "/keepout_filter_mask",
        "base": 0.0,
        "multiplier": 1.0,
    }
    si = doc["speed_costmap_filter_info_server"]["ros__parameters"]
    assert (
        si["type"] == 2
        and si["mask_topic"] == doc["speed_filter_mask_server"]["ros__parameters"]["topic_name"]
    )
    # ROS 2 refuses ints for double parameters: base/multiplier must be YAML floats.
    for info in (ki, si):
        assert isinstance(info["base"], float) and isinstance(info["multiplier"], float)
        assert isinstance(info["type"], int)
    assert si["multiplier"] == 0.02
    lm = doc["lifecycle_manager_costmap_filters"]["ros__parameters"]
    assert lm["autostart"] is True
    assert set(lm["node_names"]) == {k for k in doc if k.endswith("_server")}
    gc = doc["global_costmap"]["global_costmap"]["ros__parameters"]
    assert gc["filters"] == ["keepout_filter", "speed_filter"]
    assert gc["keepout_filter"]["plugin"] == "nav2_costmap_2d::KeepoutFilter"
    assert gc["keepout_filter"]["filter_info_topic"] == ki["filter_info_topic"]
    assert gc["speed_filter"]["filter_info_topic"] == si["filter_info_topic"]
    lc = doc["local_costmap"]["local_costmap"]["ros__parameters"]
    assert lc["filters"] == ["keepout_filter"]


def test_params_for_one_mask_and_errors(tmp_path: Path) -> None:
    doc = yaml.safe_load(filter_params_text(tmp_path / "k.yaml"))
    assert "speed_filter_mask_server" not in doc
    assert doc["global_costmap"]["global_costmap"]["ros__parameters"]["filters"] == [
        "keepout_filter"
    ]
    doc = yaml.safe_load(filter_params_text(None, tmp_path / "s.yaml"))
    assert "local_costmap" not in doc
    with pytest.raises(RasterError, match="keepout or a speed"):
        filter_params_text(None, None)
    m = _speed_map()
    with pytest.raises(RasterError, match="ask for"):
        write_filters(m, rasterize(m), tmp_path / "x.yaml", keepout=False)


def test_real_sample_keepout(real_sample, tmp_path: Path) -> None:
    m = mapkit.load(real_sample)
    g = rasterize(m, 0.1)
    files = write_filters(m, g, tmp_path / "r.yaml")
    mask = read_ros_map(files.keepout_yaml)
    assert mask.same_geometry(g)
    areas = [o for o in m.objects if o.type == "ForbiddenArea"]
    for a in areas:
        centre = np.array(a.corners()).mean(axis=0)
        assert mask.values_at([centre]).tolist() == [100]
    if not any(o.type.startswith("Forbidden") for o in m.objects):
        assert (mask.data == -1).all()
