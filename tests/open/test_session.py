"""The session core without HTTP: undo/redo round trips and tile pixels (property tests)."""

from __future__ import annotations

import io
import json
import shutil
from pathlib import Path

import numpy as np
from hypothesis import given, settings, strategies as st

import mapkit
from mapkit.edit import apply_script, diff, parse_script
from mapkit.open.session import MapSession
from mapkit.open.tiles import TILE, TileSource, tile_bounds

OFFICE = Path(__file__).resolve().parents[2] / "mapkit" / "sample_maps" / "office.map"

coord = st.integers(-20_000, 20_000)
an_edit = st.one_of(
    st.builds(
        lambda x, y, h: {"add-goal": {"name": f"G{x}_{y}", "x": x, "y": y, "heading": h}},
        coord,
        coord,
        st.integers(-179, 180),
    ),
    st.builds(
        lambda x, y, w, h: {"forbid": {"area": [x, y, x + w, y + h]}},
        coord,
        coord,
        st.integers(1, 5000),
        st.integers(1, 5000),
    ),
    st.builds(
        lambda x, y, w: {"erase": {"box": [x, y, x + w, y + w]}}, coord, coord, st.integers(1, 8000)
    ),
    st.builds(
        lambda x, y, w: {"draw-line": {"line": [x, y, x + w, y]}},
        coord,
        coord,
        st.integers(1, 8000),
    ),
)


@settings(max_examples=15, deadline=None)
@given(st.lists(an_edit, min_size=1, max_size=4))
def test_undo_all_redo_all_and_save_bytes(tmp_path_factory: object, edits: list[dict]) -> None:
    folder = tmp_path_factory.mktemp("s")  # type: ignore[attr-defined]
    path = folder / "office.map"
    shutil.copyfile(OFFICE, path)
    for i, e in enumerate(edits):  # unique names: a clash is a refusal, tested elsewhere
        if "add-goal" in e:
            e["add-goal"]["name"] = f"G{i}"
    s = MapSession.open(path)
    original = s.map
    for e in edits:
        s.edit([e])
    edited = s.map
    for _ in edits:
        s.undo()
    assert diff(original, s.map).equal and not s.dirty
    for _ in edits:
        s.redo()
    assert diff(edited, s.map).equal and s.edits == edits
    s.save()
    expected = apply_script(mapkit.load(OFFICE), parse_script(json.dumps(edits), yaml=False))
    assert path.read_bytes() == mapkit.dumpb(expected)


@settings(max_examples=60, deadline=None)
@given(
    st.integers(-12, 2),
    st.integers(-50, 50),
    st.integers(-50, 50),
    st.integers(0, TILE - 1),
    st.integers(0, TILE - 1),
)
def test_a_point_lights_its_pixel(z: int, tx: int, ty: int, col: int, row: int) -> None:
    x0, _, _, y1 = tile_bounds(z, tx, ty)
    s = 2.0**z
    x = x0 + (col + 0.5) / s
    y = y1 - (row + 0.5) / s
    src = TileSource(np.array([[x, y]]), np.zeros((0, 4)), resolution=1)
    import matplotlib.image as mpimg

    img = mpimg.imread(io.BytesIO(src.render(z, tx, ty)), format="png")
    lit = np.argwhere(img[:, :, 3] > 0)
    assert [int(row), int(col)] in lit.tolist()
    assert len(lit) <= 16  # a dot is 1 to 4 px wide


def test_a_line_across_a_tile_is_drawn_end_to_end() -> None:
    src = TileSource(np.zeros((0, 2)), np.array([[-1e6, 128.0, 1e6, 128.0]]))
    import matplotlib.image as mpimg

    img = mpimg.imread(io.BytesIO(src.render(0, 0, -1)), format="png")
    assert (img[127, :, 3] > 0).all() or (img[128, :, 3] > 0).all()
    assert (img[:120, :, 3] == 0).all() and (img[136:, :, 3] == 0).all()
