"""Scripts: YAML/JSON batches of edits, their parsing and their errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mapkit import edit
from mapkit.errors import EditError
from mapkit.formats.map import dumpb, save
from mapkit.model import MapData

SCRIPT = """\
# a batch
edits:
  - add-goal: {name: Kitchen, x: 1000, y: 2000, heading: 90}
  - op: forbid
    area: [0, 0, 2000, 1000]
    angle: 30
    rotate-about-centre: true
  - add-home: {x: 0, y: 0}
  - add-dock: {name: D, x: 5, y: 5, heading: -90}
  - add-object: {type: ForbiddenLine, line: [0, 0, 100, 0], name: L}
  - remove: [L]
  - rename: {name: kitchen, new-name: Galley}
  - move: {name: Galley, by: [0, 100]}
  - draw-line: {line: [-500, 0, 500, 0]}
  - erase: {box: [-100, -100, 100, 100]}
  - transform: {translate: [10, 0]}
  - crop: {polygon: [[-5000, -5000], [5000, -5000], [0, 5000]]}
"""


def _by_hand(m: MapData) -> MapData:
    m = edit.add_goal(m, "Kitchen", 1000, 2000, heading=90)
    m = edit.forbid_area(m, 0, 0, 2000, 1000, angle=30, rotate_about_centre=True)
    m = edit.add_home(m, 0, 0)
    m = edit.add_dock(m, "D", 5, 5, heading=-90)
    m = edit.forbid_line(m, 0, 0, 100, 0, name="L")
    m = edit.remove(m, "L")
    m = edit.rename(m, "kitchen", "Galley")
    m = edit.move(m, "Galley", by=(0, 100))
    m = edit.draw_line(m, -500, 0, 500, 0)
    m = edit.erase(m, edit.Region.box(-100, -100, 100, 100))
    m = edit.transform(m, translate=(10, 0))
    return edit.crop(m, edit.Region.polygon([(-5000, -5000), (5000, -5000), (0, 5000)]))


def test_a_script_does_what_the_functions_do() -> None:
    edits = edit.parse_script(SCRIPT, source="s.yaml")
    assert [e.op for e in edits][:3] == ["add-goal", "forbid", "add-home"]
    assert edits[1].line == 4 and edits[1].args["rotate_about_centre"] is True
    out = edit.apply_script(MapData(), edits)
    assert dumpb(out) == dumpb(_by_hand(MapData()))


def test_json_scripts(tmp_path: Path) -> None:
    doc = [{"add-goal": {"name": "A", "x": 1, "y": 2}}, {"op": "remove", "names": "A"}]
    p = tmp_path / "e.json"
    p.write_text(json.dumps(doc))
    edits = edit.load_script(p)
    assert [e.op for e in edits] == ["add-goal", "remove"] and edits[0].line is None
    assert edit.apply_script(MapData(), edits) == MapData()
    p.write_text("[{")
    with pytest.raises(EditError, match=r"e\.json:1: not valid JSON"):
        edit.load_script(p)


def test_merge_in_a_script_reads_other_relative_to_the_script(tmp_path: Path) -> None:
    other = edit.add_goal(MapData(), "From other", 0, 0)
    save(other, tmp_path / "other.map")
    (tmp_path / "s.yaml").write_text("- merge: {other: other.map, on-clash: rename}\n")
    edits = edit.load_script(tmp_path / "s.yaml")
    out = edit.apply_script(MapData(), edits, base_dir=tmp_path)
    assert [o.name for o in out.objects] == ["From other"]
    with pytest.raises(EditError, match=r"edit 1 \(merge, line 1\): .*missing.map: No such file"):
        edit.apply_script(
            MapData(), edit.parse_script("- merge: {other: missing.map}"), base_dir=tmp_path
        )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("edits: {a: 1}", "a list of edits"),
        ("other: []", "unexpected keys: other"),
        ("- 5", r"edit 1 \(line 1\)|edit 1: an edit is a mapping"),
        ("- {a: 1, b: 2}", "name the operation"),
        ("- explode: {}", "unknown operation 'explode'"),
        ("- add-goal: 5", "must be a mapping"),
        ("- add-goal: {name: A, x: 1}", "missing argument y"),
        ("- add-goal: {name: A, x: 1, y: 2, colour: red}", "unknown argument colour"),
        ("- add-goal: {name: A, x: one, y: 2}", "x must be a number"),
        (
            "- add-goal: {name: A, x: 1, y: 2}\n- add-goal: {name: a, x: 1, y: 2}",
            r"s\.yaml: edit 2 \(add-goal, line 2\): an object named 'a' already exists",
        ),
        ("- erase: {}", "give a region"),
        ("- erase: {box: [1, 2, 3]}", r"box is \[x1, y1, x2, y2\]"),
        ("- crop: {box: [0, 0, 1, 1], polygon: [[0, 0], [1, 0], [0, 1]]}", "not both"),
        ("- draw-line: {line: 5}", "line is"),
        ("- forbid: {}", "either an area or a line"),
        ("- forbid: {line: [0, 0, 1, 1], angle: 5}", "has no angle"),
        ("- ok: 1\n- [unclosed", r"s\.yaml:2: not valid YAML"),
        ("- add-home: {x: 1, y: 2, heading: [1]}", "heading must be a number"),
    ],
)
def test_script_errors_name_the_file_edit_and_line(text: str, message: str) -> None:
    with pytest.raises(EditError, match=message):
        edit.apply_script(MapData(), edit.parse_script(text, source="s.yaml"))


@pytest.mark.parametrize(
    ("spelling", "about"),
    [
        ("", "centre"),  # the default matches the CLI's
        ("rotate-about: centre", "centre"),
        ("rotate-about-centre: true", "centre"),  # scripts written before the default changed
        ("rotate-about: origin", "origin"),
        ("rotate-about-centre: false", "origin"),
    ],
)
def test_script_rotation_vocabulary(spelling: str, about: str) -> None:
    text = f"- op: forbid\n  area: [6000, 3000, 8000, 4000]\n  angle: 25\n  {spelling}\n"
    out = edit.apply_script(MapData(), edit.parse_script(text))
    want = edit.forbid_area(MapData(), 6000, 3000, 8000, 4000, angle=25, rotate_about=about)
    assert dumpb(out) == dumpb(want)
