"""mapkit's reader and writer against ARIA's own: byte-exact rewrites and ARIA's parse of each
real map."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

import mapkit
from mapkit.formats.map import written_category
from mapkit.model import MapData, MapObject


def _sha(rows: np.ndarray[Any, Any]) -> str:
    text = "".join(" ".join(str(v) for v in r) + "\n" for r in rows.tolist())
    return hashlib.sha256(text.encode()).hexdigest()


def _sorted(rows: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    if len(rows) == 0:
        return rows
    return rows[np.lexsort(rows.T[::-1])]


def test_writer_reproduces_aria_bytes(real_sample: Path, shared_dir: Path) -> None:
    expected = (shared_dir / "aria-written" / real_sample.name).read_bytes()
    m = mapkit.load(real_sample)
    assert mapkit.dumpb(m) == expected


def test_aria_output_is_a_fixed_point(real_sample: Path, shared_dir: Path) -> None:
    written = shared_dir / "aria-written" / real_sample.name
    assert mapkit.dumpb(mapkit.load(written)) == written.read_bytes()


def test_save_writes_the_same_bytes_and_returns_md5(
    real_sample: Path, shared_dir: Path, tmp_path: Path
) -> None:
    dump = json.loads(
        (shared_dir / "aria-dump" / (real_sample.stem + ".json")).read_bytes().decode()
    )
    out = tmp_path / real_sample.name
    md5 = mapkit.save(mapkit.load(real_sample), out)
    assert md5 == dump["md5_calculated"] == hashlib.md5(out.read_bytes()).hexdigest()


def _check_object(o: MapObject, d: dict[str, Any], m: MapData) -> None:
    assert o.type == d["type"]
    assert o.base_type == d["base_type"]
    assert o.name == d["name"]
    assert o.description == d["description"]
    assert o.icon == d["icon"]
    assert o.x == d["x"] and o.y == d["y"]
    assert abs(o.theta - d["th"]) < 1e-9
    assert (o.from_to is not None) == d["from_to"]
    if o.from_to is not None:
        assert o.from_to == (d["x1"], d["y1"], d["x2"], d["y2"])
    line = mapkit.dumps(MapData(objects=(o,))).splitlines()
    cairn = next(x for x in line if x.startswith("Cairn: "))
    assert cairn[len("Cairn: ") :] == d["to_string"]


def test_parse_agrees_with_aria(real_sample: Path, shared_dir: Path) -> None:
    dump = json.loads(
        (shared_dir / "aria-dump" / (real_sample.stem + ".json")).read_bytes().decode()
    )
    assert dump["ok"]
    m = mapkit.load(real_sample)
    assert written_category(m) == dump["version_header"]
    assert [s.name for s in m.scans] == dump["scan_types"]
    assert m.md5 == dump["md5_read"]
    for scan in m.scans:
        d = dump["scans"][scan.name]
        assert scan.num_points == d["points_loaded"] == d["num_points"]
        assert scan.num_lines == d["lines_loaded"] == d["num_lines"]
        assert scan.resolution == d["resolution"]
        assert scan.points_sorted == d["points_are_sorted"]
        assert scan.lines_sorted == d["lines_are_sorted"]
        assert list(scan.min_pos or (0, 0)) == d["min_pos"]
        assert list(scan.max_pos or (0, 0)) == d["max_pos"]
        assert list(scan.line_min_pos or (0, 0)) == d["line_min_pos"]
        assert list(scan.line_max_pos or (0, 0)) == d["line_max_pos"]
        assert _sha(scan.points) == d["points_sha256_ordered"]
        assert _sha(_sorted(scan.points)) == d["points_sha256_sorted"]
        assert _sha(scan.lines) == d["lines_sha256_ordered"]
        assert _sha(_sorted(scan.lines)) == d["lines_sha256_sorted"]
        assert int(scan.points[:, 0].sum()) == d["points_sum_x"]
        assert int(scan.points[:, 1].sum()) == d["points_sum_y"]
        assert int(scan.lines.sum()) == d["lines_sum"]
    assert m.scan.display == dump["display"]
    for key, objs in (
        ("objects", m.objects),
        ("inactive_objects", m.inactive_objects),
        ("child_objects", m.child_objects),
    ):
        assert len(objs) == len(dump[key])
        for o, d in zip(objs, dump[key], strict=True):
            _check_object(o, d, m)
    for key, info in (("info", m.info), ("inactive_info", m.inactive_info)):
        expected = {
            k.rstrip(":").lstrip("_"): [tuple(x["args"]) for x in v] for k, v in dump[key].items()
        }
        assert {k: list(v) for k, v in info.items()} == expected
        for k, v in dump[key].items():
            keyword = k.rstrip(":").lstrip("_")
            assert [" ".join(t) for t in info[keyword]] == [x["full"] for x in v]
    assert m.origin_lla == (tuple(dump["origin_lla"]) if dump["origin_lla"] else None)
    assert list(m.remainder) == [x["full"] for x in dump["remainder"]]
