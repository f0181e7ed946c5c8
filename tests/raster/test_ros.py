"""ROS map_server maps: written field by field as map_server reads them, read back by its rules."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

import mapkit
from mapkit.raster import OccupancyGrid, RasterError, RosMapError, rasterize
from mapkit.raster.ros import (
    grid_to_image,
    load_pixel_values,
    read_ros_map,
    read_ros_yaml,
    write_ros_map,
)

from .rosloader import cells, decode, parse_map_yaml

trinary_data = hnp.arrays(
    np.int8,
    hnp.array_shapes(min_dims=2, max_dims=2, max_side=12),
    elements=st.sampled_from([-1, 0, 100]),
)
any_data = hnp.arrays(np.int8, hnp.array_shapes(min_dims=2, max_dims=2, max_side=12))
origins = st.tuples(st.floats(-1e4, 1e4), st.floats(-1e4, 1e4))
resolutions = st.sampled_from([0.01, 0.025, 0.05, 0.1, 0.3])


@given(trinary_data, resolutions, origins, st.booleans(), st.booleans())
@settings(max_examples=40)
def test_trinary_maps_load_as_written(tmp_path_factory, data, res, origin, png, negate) -> None:
    folder = tmp_path_factory.mktemp("m")
    g = OccupancyGrid(data, res, origin)
    files = write_ros_map(
        g, folder / "map.yaml", image_format="png" if png else None, negate=negate
    )
    assert files.image.name == ("map.png" if png else "map.pgm")
    loaded, doc = cells(files.yaml)
    assert np.array_equal(loaded, g.data)
    # Field by field.
    assert doc["image"] == files.image.name  # relative to the YAML's folder
    assert doc["resolution"] == res
    assert doc["origin"] == [g.origin[0], g.origin[1], 0.0]
    assert doc["negate"] == int(negate)
    assert (doc["occupied_thresh"], doc["free_thresh"]) == (0.65, 0.196)
    assert doc["mode"] == "trinary"
    grey, alpha = decode(files.image)
    assert alpha is None
    want = {-1: 205, 0: 254, 100: 0}
    expect = np.vectorize(want.get)(g.data[::-1])
    assert np.array_equal(grey, 255 - expect if negate else expect)
    # mapkit's own reader agrees, in both flavours.
    assert read_ros_map(files.yaml) == g
    assert read_ros_map(files.yaml, flavor="nav2") == g


def test_pgm_header_and_rows_like_map_saver(tmp_path: Path) -> None:
    data = np.array([[0, 100, -1], [-1, -1, 0]], dtype=np.int8)  # row 0 is south
    files = write_ros_map(OccupancyGrid(data, 0.05, (1.5, -2.0)), tmp_path / "m.yaml")
    raw = files.image.read_bytes()
    header, body = raw[:-6], raw[-6:]
    assert header.startswith(b"P5\n# CREATOR: mapkit 0.050 m/pix\n3 2\n255\n")
    assert body == bytes([205, 205, 254, 254, 0, 205])  # north row first
    assert files.yaml.read_text().splitlines()[0] == "image: m.pgm"


@given(any_data, st.booleans())
@settings(max_examples=40)
def test_raw_mode_round_trips_every_value(tmp_path_factory, data, png) -> None:
    folder = tmp_path_factory.mktemp("m")
    g = OccupancyGrid(data, 0.05, (0.0, 0.0))
    files = write_ros_map(g, folder / "raw.yaml", mode="raw", image_format="png" if png else None)
    loaded, doc = cells(files.yaml)
    assert doc["mode"] == "raw" and doc["negate"] == 0
    assert np.array_equal(loaded, g.data)
    assert read_ros_map(files.yaml) == g
    nav2 = read_ros_map(files.yaml, flavor="nav2").data
    inside = (g.data >= 0) & (g.data <= 100)
    assert np.array_equal(nav2[inside], g.data[inside]) and (nav2[~inside] == -1).all()


@given(hnp.arrays(np.int8, (6, 7), elements=st.integers(-1, 100)))
@settings(max_examples=40)
def test_scale_mode_reads_back_within_a_level(tmp_path_factory, data) -> None:
    folder = tmp_path_factory.mktemp("m")
    g = OccupancyGrid(data, 0.05, (0.0, 0.0))
    files = write_ros_map(g, folder / "s.yaml", mode="scale")
    unknown = g.data < 0
    assert files.image.suffix == ".png"
    loaded, _ = cells(files.yaml)
    assert (loaded[unknown] == -1).all()
    assert np.abs(loaded[~unknown].astype(int) - g.data[~unknown]).max(initial=0) <= 1
    assert np.array_equal(read_ros_map(files.yaml).data, loaded)
    nav2 = read_ros_map(files.yaml, flavor="nav2").data
    assert (nav2[unknown] == -1).all()
    assert np.abs(nav2[~unknown].astype(int) - g.data[~unknown]).max(initial=0) <= 2
    # Exact at the ends.
    assert (loaded[g.data == 0] == 0).all() and (loaded[g.data == 100] == 100).all()


def test_custom_thresholds_pick_pixels_that_load_right(tmp_path: Path) -> None:
    g = OccupancyGrid(np.array([[-1, 0, 100]], dtype=np.int8), 0.1, (0, 0))
    files = write_ros_map(g, tmp_path / "t.yaml", occupied_thresh=0.9, free_thresh=0.5)
    loaded, doc = cells(files.yaml)
    assert (doc["occupied_thresh"], doc["free_thresh"]) == (0.9, 0.5)
    assert np.array_equal(loaded, g.data)
    with pytest.raises(RasterError, match="thresholds must satisfy"):
        write_ros_map(g, tmp_path / "x.yaml", occupied_thresh=0.2, free_thresh=0.5)
    with pytest.raises(RasterError, match="no grey level"):
        write_ros_map(g, tmp_path / "x.yaml", occupied_thresh=0.5, free_thresh=0.499)


def test_write_errors(tmp_path: Path) -> None:
    g = OccupancyGrid(np.array([[-1, 0]], dtype=np.int8), 0.1, (0, 0))
    with pytest.raises(RasterError, match="needs transparency"):
        write_ros_map(g, tmp_path / "a.yaml", mode="scale", image_format="pgm")
    with pytest.raises(RasterError, match="mode must be one of"):
        write_ros_map(g, tmp_path / "a.yaml", mode="binary")  # type: ignore[arg-type]
    with pytest.raises(RasterError, match="negate is not supported in raw"):
        write_ros_map(g, tmp_path / "a.yaml", mode="raw", negate=True)
    with pytest.raises(RasterError, match="pgm or png"):
        write_ros_map(g, tmp_path / "a.yaml", image_format="jpg")
    with pytest.raises(RasterError, match="same file"):
        write_ros_map(g, tmp_path / "a.pgm", image_path=tmp_path / "a.pgm")
    assert not list(tmp_path.iterdir())


def test_image_elsewhere_and_odd_names(tmp_path: Path) -> None:
    g = OccupancyGrid(np.zeros((2, 2), dtype=np.int8), 0.1, (0, 0))
    (tmp_path / "sub").mkdir()
    (tmp_path / "other").mkdir()
    f = write_ros_map(
        g, tmp_path / "sub" / "my map.yaml", image_path=tmp_path / "other" / "a #1.pgm"
    )
    doc = parse_map_yaml(f.yaml)
    assert doc["image"] == str((tmp_path / "other" / "a #1.pgm").resolve())
    assert read_ros_map(f.yaml) == g
    f = write_ros_map(g, tmp_path / "sub" / "yes.yaml", image_path=tmp_path / "sub" / "true")
    assert parse_map_yaml(f.yaml)["image"] == "true"


# -- reading maps made elsewhere ------------------------------------------------------------------


def _png(path: Path, arr: np.ndarray, mode: str) -> None:
    from PIL import Image

    Image.fromarray(arr, mode).save(path)


def _yaml(
    path: Path,
    image: str,
    mode: str | None = None,
    negate: str = "0",
    occ: str = "0.65",
    free: str = "0.196",
    extra: str = "",
) -> Path:
    text = (
        f"image: {image}\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\nnegate: {negate}\n"
        f"occupied_thresh: {occ}\nfree_thresh: {free}\n{extra}"
    )
    if mode:
        text += f"mode: {mode}\n"
    path.write_text(text)
    return path


def test_reader_documented_grey_levels(tmp_path: Path) -> None:
    levels = np.arange(256, dtype=np.uint8).reshape(16, 16)
    _png(tmp_path / "g.png", levels, "L")
    g = read_ros_map(_yaml(tmp_path / "g.yaml", "g.png"))
    flat = g.data[::-1].reshape(-1)
    assert (flat[:90] == 100).all() and (flat[90:206] == -1).all() and (flat[206:] == 0).all()
    assert g.origin == (-1.0, 2.0) and g.resolution == 0.05
    neg = read_ros_map(_yaml(tmp_path / "n.yaml", "g.png", negate="1")).data[::-1].reshape(-1)
    assert (neg[:50] == 0).all() and (neg[166:] == 100).all()
    raw = read_ros_map(_yaml(tmp_path / "r.yaml", "g.png", mode="raw")).data[::-1].reshape(-1)
    assert raw[255] == -1 and raw[205] == -51 and raw[100] == 100
    scale = read_ros_map(_yaml(tmp_path / "s.yaml", "g.png", mode="scale")).data[::-1].reshape(-1)
    assert scale[205] == 1 and scale[90] == 98 and scale[89] == 100 and scale[206] == 0


def test_reader_alpha_rgb_palette_16bit(tmp_path: Path) -> None:
    # Trinary averages alpha in: an opaque 205 grey (unknown) reads as free.
    la = np.zeros((1, 2, 2), dtype=np.uint8)
    la[0, 0] = (205, 255)
    la[0, 1] = (0, 255)
    _png(tmp_path / "la.png", la, "LA")
    g = read_ros_map(_yaml(tmp_path / "la.yaml", "la.png"))
    assert g.data.tolist() == [[0, 100]]  # (205*3+255)/4 = 217.5 -> free; 63.75 -> occupied
    # Scale mode: transparent pixels are unknown.
    la[0, 1] = (120, 0)
    _png(tmp_path / "la2.png", la, "LA")
    g = read_ros_map(_yaml(tmp_path / "s.yaml", "la2.png", mode="scale"))
    assert g.data[0, 1] == -1
    assert (
        read_ros_map(_yaml(tmp_path / "s2.yaml", "la2.png", mode="scale"), flavor="nav2").data[0, 1]
        == -1
    )
    # RGB in scale mode: ROS 1 takes the blue byte as alpha (blue 0 -> unknown), Nav2 does not.
    rgb = np.array([[[150, 150, 0], [100, 100, 100]]], dtype=np.uint8)
    _png(tmp_path / "rgb.png", rgb, "RGB")
    y = _yaml(tmp_path / "rgb.yaml", "rgb.png", mode="scale")
    assert read_ros_map(y).data[0, 0] == -1
    assert read_ros_map(y, flavor="nav2").data[0, 0] >= 0
    # Palette: ROS 1 uses the index, Nav2 the colour.
    from PIL import Image

    im = Image.fromarray(np.array([[0, 1]], dtype=np.uint8), "P")
    im.putpalette([255, 255, 255, 0, 0, 0] + [0] * 762)
    im.save(tmp_path / "p.png")
    y = _yaml(tmp_path / "p.yaml", "p.png")
    assert read_ros_map(y).data.tolist() == [[100, 100]]
    assert read_ros_map(y, flavor="nav2").data.tolist() == [[0, 100]]
    # 16-bit grey PNG: ROS 1 keeps the high byte.
    Image.fromarray(np.array([[0xFE00, 0x0100]], dtype=np.uint16)).save(tmp_path / "w.png")
    assert read_ros_map(_yaml(tmp_path / "w.yaml", "w.png")).data.tolist() == [[0, 100]]


def test_reader_pnm_variants(tmp_path: Path) -> None:
    (tmp_path / "a.pgm").write_bytes(b"P2\n# comment\n3 1\n# more\n15\n15 0 8\n")
    g = read_ros_map(_yaml(tmp_path / "a.yaml", "a.pgm"))
    assert g.data.tolist() == [[0, 100, -1]]  # maxval 15 rescaled: 8 -> 136
    (tmp_path / "b.pbm").write_bytes(b"P1\n2 1\n1 0\n")
    assert read_ros_map(_yaml(tmp_path / "b.yaml", "b.pbm")).data.tolist() == [[100, 100]]
    assert read_ros_map(_yaml(tmp_path / "b2.yaml", "b.pbm"), flavor="nav2").data.tolist() == [
        [100, 0]
    ]
    (tmp_path / "c.pgm").write_bytes(b"P5 2 1 65535\n" + bytes([255, 255, 0, 0]))
    with pytest.raises(RosMapError, match="16-bit PGM"):
        read_ros_map(_yaml(tmp_path / "c.yaml", "c.pgm"))
    assert read_ros_map(_yaml(tmp_path / "c2.yaml", "c.pgm"), flavor="nav2").data.tolist() == [
        [0, 100]
    ]
    (tmp_path / "d.ppm").write_bytes(b"P6\n1 1\n255\n" + bytes([0, 255, 255]))  # mean 170: unknown
    assert read_ros_map(_yaml(tmp_path / "d.yaml", "d.ppm")).data.tolist() == [[-1]]
    (tmp_path / "e.pgm").write_bytes(b"P5\n4 4\n255\n" + bytes(3))
    with pytest.raises(RosMapError, match="truncated"):
        read_ros_map(_yaml(tmp_path / "e.yaml", "e.pgm"))


def test_yaml_syntax_map_server_accepts(tmp_path: Path) -> None:
    _png(tmp_path / "g.png", np.array([[0, 254]], dtype=np.uint8), "L")
    text = (
        "# a comment\r\n{image: g.png, resolution: '5e-2', origin: [1, 2, 0.5, 9],\r\n"
        ' negate: 0, occupied_thresh: "0.65", free_thresh: 0.196, extra: ignored}\r\n'
    )
    (tmp_path / "f.yaml").write_bytes(text.encode())
    info = read_ros_yaml(tmp_path / "f.yaml")
    assert info.resolution == 0.05 and info.origin == (1.0, 2.0, 0.5) and info.mode == "trinary"
    assert read_ros_map(tmp_path / "f.yaml").data.tolist() == [[100, 0]]


@pytest.mark.parametrize(
    ("body", "flavor", "message"),
    [
        (
            "image: g.png\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\nfree_thresh: 0.1\n",
            "ros1",
            "missing required key 'occupied_thresh'",
        ),
        (
            "image: g.png\nresolution: 0.05\norigin: [0, 0]\nnegate: 0\noccupied_thresh: 0.6\n"
            "free_thresh: 0.1\n",
            "ros1",
            ":3: origin needs at least 3",
        ),
        (
            "image: g.png\nresolution: 0.05\norigin: [0, 0, 0, 0]\nnegate: 0\n"
            "occupied_thresh: 0.6\n"
            "free_thresh: 0.1\n",
            "nav2",
            "exactly 3",
        ),
        (
            "image: g.png\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: true\n"
            "occupied_thresh: 0.6\n"
            "free_thresh: 0.1\n",
            "ros1",
            ":4: negate must be an integer",
        ),
        (
            "image: g.png\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 1.0\noccupied_thresh: 0.6\n"
            "free_thresh: 0.1\n",
            "ros1",
            "negate must be an integer",
        ),
        (
            "image: g.png\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.6\n"
            "free_thresh: 0.1\nmode: Trinary\n",
            "ros1",
            ":7: mode must be",
        ),
        (
            "image: ''\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.6\n"
            "free_thresh: 0.1\n",
            "ros1",
            "empty string",
        ),
        (
            "image: g.png\nresolution: fast\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.6\n"
            "free_thresh: 0.1\n",
            "ros1",
            ":2: resolution must be a number",
        ),
        (
            "image: g.png\nresolution: -1\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.6\n"
            "free_thresh: 0.1\n",
            "ros1",
            "positive",
        ),
        (
            "image: g.png\nresolution: 0.05\norigin: 7\nnegate: 0\noccupied_thresh: 0.6\n"
            "free_thresh: 0.1\n",
            "ros1",
            "origin must be a list",
        ),
        ("image: [g.png\n", "ros1", "not valid YAML"),
        ("- just a list\n", "ros1", "mapping of keys"),
        (
            "image: missing.png\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
            "occupied_thresh: 0.6\nfree_thresh: 0.1\n",
            "ros1",
            "missing.png: image file not found",
        ),
    ],
)
def test_yaml_errors_name_file_and_line(tmp_path: Path, body, flavor, message) -> None:
    _png(tmp_path / "g.png", np.zeros((1, 1), dtype=np.uint8), "L")
    (tmp_path / "bad.yaml").write_text(body)
    with pytest.raises(RosMapError, match=message.replace("[", r"\[")) as info:
        read_ros_map(tmp_path / "bad.yaml", flavor=flavor)
    assert ("bad.yaml" in str(info.value)) or ("missing.png" in str(info.value))


def test_nav2_accepts_boolean_negate(tmp_path: Path) -> None:
    _png(tmp_path / "g.png", np.array([[0, 254]], dtype=np.uint8), "L")
    y = _yaml(tmp_path / "b.yaml", "g.png", negate="true")
    assert read_ros_map(y, flavor="nav2").data.tolist() == [[0, 100]]
    with pytest.raises(RosMapError, match="no such file"):
        read_ros_yaml(tmp_path / "nothing.yaml")


def test_load_pixel_values_rules() -> None:
    p = np.arange(256)
    t = load_pixel_values(p, "trinary")
    occ = (255 - p) / 255
    assert np.array_equal(t, np.where(occ > 0.65, 100, np.where(occ < 0.196, 0, -1)))
    with pytest.raises(RasterError, match="flavor"):
        load_pixel_values(p, "trinary", flavor="ros3")  # type: ignore[arg-type]
    with pytest.raises(RasterError, match="mode must be"):
        load_pixel_values(p, "binary")


def test_grid_to_image_is_north_up() -> None:
    g = OccupancyGrid(np.array([[100, 100], [0, 0]], dtype=np.int8), 0.1, (0, 0))
    grey, alpha = grid_to_image(g)
    assert grey.tolist() == [[254, 254], [0, 0]] and alpha is None


def test_real_samples_round_trip_through_ros(real_sample, tmp_path: Path) -> None:
    m = mapkit.load(real_sample)
    g = rasterize(m, 0.05)
    files = write_ros_map(g, tmp_path / "r.yaml")
    loaded, doc = cells(files.yaml)
    assert np.array_equal(loaded, g.data)
    assert read_ros_map(files.yaml) == g
    # The origin is the lower-left corner: the map's minimum lies in the image's bottom-left area.
    (x0, y0), _ = g.bounds_mm()
    assert math.isclose(doc["origin"][0] * 1000, x0) and math.isclose(doc["origin"][1] * 1000, y0)


def test_png_written_is_valid_for_pillow(tmp_path: Path) -> None:
    from PIL import Image

    g = OccupancyGrid(np.array([[0, 100, -1]], dtype=np.int8), 0.1, (0, 0))
    f = write_ros_map(g, tmp_path / "p.yaml", image_format="png")
    with Image.open(f.image) as im:
        assert im.mode == "L" and np.asarray(im).tolist() == [[254, 0, 205]]


def test_palette_with_transparency(tmp_path: Path) -> None:
    from PIL import Image

    im = Image.fromarray(np.array([[0, 1, 2]], dtype=np.uint8), "P")
    im.putpalette([255, 255, 255, 0, 0, 0, 128, 128, 128] + [0] * 759)
    im.info["transparency"] = 2
    im.save(tmp_path / "t.png", transparency=2)
    y = _yaml(tmp_path / "t.yaml", "t.png", mode="scale")
    assert read_ros_map(y).data.tolist() == [[100, 100, 100]]  # indices 0, 1, 2: all dark
    assert read_ros_map(y, flavor="nav2").data.tolist() == [[0, 100, -1]]
