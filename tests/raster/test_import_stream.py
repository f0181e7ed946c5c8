"""import-ros reads the image in row bands: the same map as the whole-image path, in bands.

The whole-image path is :func:`grid_to_map` of :func:`read_ros_map`'s grid (the grid held whole).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

import mapkit
from mapkit.model import MapData
from mapkit.raster import OccupancyGrid, rasterize
from mapkit.raster.import_ros import grid_to_map, import_ros
from mapkit.raster.ros import read_ros_map, write_ros_map
from mapkit.raster.ros_image import ImageSource


def same(a: MapData, b: MapData) -> None:
    assert np.array_equal(a.points, b.points)  # same order too
    assert np.array_equal(a.lines, b.lines)
    assert a == b


def whole(yaml_path: Path, flavor: str = "ros1", **kw: Any) -> MapData:
    grid = read_ros_map(yaml_path, flavor=flavor)  # type: ignore[arg-type]
    return grid_to_map(grid, **kw)


def test_every_shared_sample_imports_the_same_in_bands(real_sample: Path, tmp_path: Path) -> None:
    grid = rasterize(mapkit.load(real_sample), 0.05)
    files = write_ros_map(grid, tmp_path / "s.yaml")
    expected = whole(files.yaml)
    assert expected.scan.num_points and expected.scan.num_lines
    for rows in (1, 37, None):
        same(import_ros(files.yaml, band_rows=rows), expected)
    same(import_ros(files.yaml, band_rows=5, lines=False), whole(files.yaml, lines=False))
    # A turned origin rotates both paths alike.
    yaw = 0.3
    files.yaml.write_text(files.yaml.read_text().replace(", 0.0]", f", {yaw!r}]"))
    same(import_ros(files.yaml, band_rows=11), whole(files.yaml, yaw=yaw))


@given(
    hnp.arrays(
        np.int8,
        st.tuples(st.integers(1, 30), st.integers(1, 30)),
        elements=st.sampled_from([-1, 0, 0, 100, 100, 37, 80]),
    ),
    st.integers(1, 8),
    st.sampled_from(["trinary", "scale", "raw"]),
    st.sampled_from(["ros1", "nav2"]),
    st.sampled_from([0.0, 0.1, 0.5]),
)
@settings(max_examples=80, deadline=None)
def test_bands_equal_the_whole_image(
    tmp_path_factory: pytest.TempPathFactory,
    data: np.ndarray,
    rows: int,
    mode: str,
    flavor: str,
    min_line: float,
) -> None:
    g = OccupancyGrid(data, 0.05, (-0.35, 1.2))
    fmt = "png" if mode == "scale" else "pgm"
    files = write_ros_map(
        g,
        tmp_path_factory.mktemp("b") / "m.yaml",
        mode=mode,  # type: ignore[arg-type]
        image_format=fmt,
    )
    got = import_ros(
        files.yaml,
        band_rows=rows,
        flavor=flavor,  # type: ignore[arg-type]
        min_line_m=min_line,
        occupied_value=50,
    )
    same(got, whole(files.yaml, flavor, min_line_m=min_line, occupied_value=50))


def test_binary_pgm_is_read_band_by_band(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(3)
    g = OccupancyGrid(rng.choice(np.array([-1, 0, 100], dtype=np.int8), (200, 50)), 0.05, (0, 0))
    files = write_ros_map(g, tmp_path / "m.yaml")
    spans: list[tuple[int, int]] = []
    real = ImageSource.read_rows

    def spy(self: ImageSource, top: int, bottom: int) -> Any:
        assert self.streamed  # rows come from the file, not from a decoded image
        spans.append((top, bottom))
        return real(self, top, bottom)

    monkeypatch.setattr(ImageSource, "read_rows", spy)
    done: list[tuple[int, int]] = []
    m = import_ros(files.yaml, band_rows=16, progress=lambda d, t: done.append((d, t)))
    assert max(b - t for t, b in spans) <= 16 + 2  # a band and its two halo rows
    assert len(spans) == math.ceil(200 / 16) and done[-1] == (200, 200)
    monkeypatch.setattr(ImageSource, "read_rows", real)
    same(m, whole(files.yaml))


def test_default_band_follows_the_width(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import mapkit.raster.import_ros as mod

    g = OccupancyGrid(np.full((64, 40), 100, dtype=np.int8), 0.05, (0, 0))
    files = write_ros_map(g, tmp_path / "m.yaml")
    monkeypatch.setattr(mod, "BAND_CELLS", 40 * 10)  # ten rows a band
    done: list[int] = []
    same(import_ros(files.yaml, progress=lambda d, _t: done.append(d)), whole(files.yaml))
    assert done == [10, 20, 30, 40, 50, 60, 64]


def reference_wall_cells(occ: np.ndarray, n: int) -> np.ndarray:
    """Wall runs as the whole-grid code found them before banding (a grid-sized coverage mask)."""
    from mapkit.raster.import_ros import _run_cells, cell_runs

    p = np.pad(occ, 1)
    faces = occ & ~(p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:])
    runs = cell_runs(faces, 2)
    axis = (runs[:, 0] == runs[:, 2]) | (runs[:, 1] == runs[:, 3])
    length = np.maximum(np.abs(runs[:, 2] - runs[:, 0]), np.abs(runs[:, 3] - runs[:, 1])) + 1
    straight, diag = runs[axis & (length >= n)], runs[~axis & (length * math.sqrt(2) >= n)]
    if len(diag):
        w = faces.shape[1]
        covered = np.zeros(faces.size, dtype=bool)
        _, rr, cc = _run_cells(straight)
        covered[rr * w + cc] = True
        rid, rr, cc = _run_cells(diag)
        hits = np.bincount(rid, weights=covered[rr * w + cc], minlength=len(diag))
        diag = diag[hits / np.bincount(rid, minlength=len(diag)) < 0.5]
    return np.concatenate([straight, diag])


@given(hnp.arrays(np.bool_, st.tuples(st.integers(1, 40), st.integers(1, 40))), st.integers(2, 6))
@settings(max_examples=150, deadline=None)
def test_face_lines_match_the_grid_sized_coverage(occ: np.ndarray, n: int) -> None:
    from mapkit.raster.import_ros import _face_lines, _faces

    faces = _faces(np.pad(occ, 1), 1, occ.shape[0] + 1)
    rc = np.argwhere(faces).astype(np.int64)
    got = _face_lines(rc, n) if len(rc) else np.zeros((0, 4), dtype=np.int64)
    assert np.array_equal(got, reference_wall_cells(occ, n))


@given(
    w=st.integers(1, 100_000),
    h=st.integers(1, 100_000),
    comment=st.sampled_from([b"", b"# made by hand\n", b"#x\r"]),
    magic=st.sampled_from([b"P1", b"P2", b"P4", b"P5", b"P6"]),
)
@settings(max_examples=40, deadline=None)
def test_the_image_size_is_read_from_the_header_alone(
    tmp_path_factory: pytest.TempPathFactory, w: int, h: int, comment: bytes, magic: bytes
) -> None:
    """``image_size`` reads what the decoder's own header reader reads, with no pixels there
    (a server refuses an over-large image before decoding it)."""
    from mapkit.raster.ros_image import image_size

    d = tmp_path_factory.mktemp("size")
    maxval = b"" if magic in (b"P1", b"P4") else b" 255"
    (d / "a.pgm").write_bytes(magic + b"\n" + comment + b"%d %d" % (w, h) + maxval + b"\n")
    assert image_size(d / "a.pgm") == (w, h)
    png = (
        b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\x0dIHDR" + w.to_bytes(4, "big") + h.to_bytes(4, "big")
    )
    (d / "a.png").write_bytes(png + b"\x08\x00\x00\x00\x00")
    assert image_size(d / "a.png") == (w, h)
    (d / "bad.pgm").write_bytes(magic + b" x 1 255\n")
    assert image_size(d / "bad.pgm") is None
    assert image_size(d / "missing.pgm") is None
    assert image_size(d) is None  # a folder
    if hasattr(os, "mkfifo"):  # each example has a fresh folder
        os.mkfifo(d / "pipe.pgm")  # read, it would wait for a writer forever
        assert image_size(d / "pipe.pgm") is None
