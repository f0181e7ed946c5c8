"""Hostile and odd ROS maps: every field of the YAML, every image variant, mapkit's own error.

Each bad input must raise a :class:`~mapkit.errors.MapkitError` that names the file (the YAML or
the image); odd but valid input (anchors, comments in PNM headers, palettes, 16-bit for Nav2)
must import.
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from mapkit.errors import MapkitError
from mapkit.raster.import_ros import import_ros
from mapkit.raster.ros import read_ros_map

GOOD = {
    "image": "m.pgm",
    "resolution": "0.05",
    "origin": "[-1.0, 2.0, 0.0]",
    "negate": "0",
    "occupied_thresh": "0.65",
    "free_thresh": "0.196",
}
PGM = b"P5\n# CREATOR: test\n3 2\n255\n" + bytes([0, 254, 205, 0, 0, 254])


def yaml_text(**fields: str | None) -> str:
    values = {**GOOD, **fields}
    return "".join(f"{k}: {v}\n" for k, v in values.items() if v is not None)


def png_bytes(
    w: int,
    h: int,
    raw: bytes,
    *,
    depth: int = 8,
    color: int = 0,
    extra: list[tuple[bytes, bytes]] | None = None,
) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = struct.pack(">I", zlib.crc32(kind + data))
        return struct.pack(">I", len(data)) + kind + data + crc

    ihdr = struct.pack(">IIBBBBB", w, h, depth, color, 0, 0, 0)
    return b"".join(
        [
            b"\x89PNG\r\n\x1a\n",
            chunk(b"IHDR", ihdr),
            *(chunk(k, d) for k, d in (extra or [])),
            chunk(b"IDAT", zlib.compress(raw)),
            chunk(b"IEND", b""),
        ]
    )


def expect_error(yaml_path: Path, names: str, **kw: object) -> MapkitError:
    with pytest.raises(MapkitError) as e:
        import_ros(yaml_path, **kw)  # type: ignore[arg-type]
    assert names in str(e.value), str(e.value)
    return e.value


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    (tmp_path / "m.pgm").write_bytes(PGM)
    return tmp_path


# -- every YAML field ------------------------------------------------------------------------

BAD_FIELDS = [
    ("image", None),
    ("image", '""'),
    ("image", "[a.pgm]"),
    ("image", "{a: 1}"),
    ("image", '"m\\0.pgm"'),
    ("image", "x" * 300 + ".pgm"),
    ("image", "."),
    ("image", "gone.pgm"),
    ("image", "m.pgm/inner.pgm"),
    ("image", "/dev/zero"),
    ("image", "/dev/null"),
    ("resolution", None),
    ("resolution", "abc"),
    ("resolution", "[0.05]"),
    ("resolution", "0"),
    ("resolution", "-0.05"),
    ("resolution", ".nan"),
    ("resolution", ".inf"),
    ("resolution", "1e309"),
    ("resolution", "1e308"),
    ("resolution", "1" * 5000),
    ("resolution", "0x10"),
    ("resolution", "0." + "5" * 5000 + "x"),
    ("resolution", "~"),
    ("origin", None),
    ("origin", "0"),
    ("origin", "[0, 0]"),
    ("origin", "{x: 0}"),
    ("origin", "[[0], 0, 0]"),
    ("origin", "[a, 0, 0]"),
    ("origin", "[.nan, 0, 0]"),
    ("origin", "[0, .inf, 0]"),
    ("origin", "[0, 0, .nan]"),
    ("origin", "[1e300, 0, 0]"),
    ("origin", "[0, -3e6, 0]"),
    ("origin", "[" + "9" * 5000 + ", 0, 0]"),
    ("negate", None),
    ("negate", "09"),
    ("negate", "1.0"),
    ("negate", "true"),
    ("negate", "1" * 5000),
    ("negate", "2147483648"),
    ("negate", "[0]"),
    ("negate", "0o7"),
    ("negate", "''"),
    ("occupied_thresh", None),
    ("occupied_thresh", "high"),
    ("occupied_thresh", ".nan"),
    ("occupied_thresh", "-.inf"),
    ("occupied_thresh", "[0.6]"),
    ("free_thresh", ".inf"),
    ("free_thresh", "1e400"),
    ("free_thresh", "{}"),
    ("mode", "Trinary"),
    ("mode", "1"),
    ("mode", "[scale]"),
    ("mode", "''"),
]


@pytest.mark.parametrize(("key", "value"), BAD_FIELDS)
def test_every_bad_field_is_mapkits_error_naming_the_file(
    folder: Path, key: str, value: str | None
) -> None:
    y = folder / "m.yaml"
    y.write_text(yaml_text(**{key: value}))
    err = expect_error(y, "m", flavor="ros1")
    assert "m.yaml" in str(err) or key == "image"


@pytest.mark.parametrize("flavor", ["ros1", "nav2"])
def test_scale_with_equal_thresholds_is_refused(folder: Path, flavor: str) -> None:
    y = folder / "m.yaml"
    y.write_text(yaml_text(occupied_thresh="0.5", free_thresh="0.5") + "mode: scale\n")
    expect_error(y, "m.yaml:", flavor=flavor)
    y.write_text(yaml_text(occupied_thresh="0.5", free_thresh="0.5"))  # trinary: defined
    assert import_ros(y, flavor=flavor).scan.num_points == 3  # type: ignore[arg-type]


ODD_YAML = [
    "- image: m.pgm\n",  # a list
    "just text\n",
    "",
    "~\n",
    yaml_text() + "resolution: 0.1\n",  # a key twice
    yaml_text() + "---\n" + yaml_text(),  # two documents
    "image: m.pgm\n\tresolution: 0.05\n",  # a tab
    "a: " + "[" * 100_000 + "\n",  # nested deeper than the composer can recurse
    "a: " + "{b: " * 5000 + "\n",
    yaml_text(origin="*nowhere"),  # an undefined alias
    "x: " + "y" * (2 << 20) + "\n",  # over the size limit
    yaml_text(origin="[" + "0, " * 20_000 + "0]"),  # too many values to compose quickly
    yaml_text() + "".join(f"k{i}: {i}\n" for i in range(5000)),
    yaml_text() + "b: [" + "*a, " * 5000 + "]\n",
]


@pytest.mark.parametrize("text", ODD_YAML, ids=range(len(ODD_YAML)))
def test_odd_yaml_is_mapkits_error(folder: Path, text: str) -> None:
    y = folder / "m.yaml"
    y.write_text(text)
    expect_error(y, "m.yaml")


def test_invalid_utf8_and_alias_bombs(folder: Path) -> None:
    y = folder / "m.yaml"
    y.write_bytes(yaml_text().encode() + b"note: \xff\xfe\n")
    expect_error(y, "m.yaml")
    # A billion laughs: aliases are not expanded, so this is quick and small.
    bomb = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
        for p, c in zip("abcdefgh", "bcdefghi", strict=True)
    )
    y.write_text(bomb + yaml_text(origin="*i"))
    expect_error(y, "origin must hold numbers")
    y.write_text("r: &r [*r]\n" + yaml_text(origin="&s [*s, 0, 0]"))
    expect_error(y, "m.yaml")


def test_odd_but_valid_yaml_imports(folder: Path) -> None:
    y = folder / "m.yaml"
    y.write_text(yaml_text(image="!!python/object:os.system m.pgm"))  # tags are not acted on
    assert import_ros(y).scan.num_points == 3
    y.write_text(
        "\ufeff# comment\r\n"
        + yaml_text(origin="&o [-1.0, 2.0, 0.0]", resolution="'5e-2'", negate="0x0").replace(
            "\n", "\r\n"
        )
        + "again: *o\nextra: {nested: [1, 2]}\n"
    )
    assert import_ros(y).scan.num_points == 3


def test_yaml_path_that_is_no_file(folder: Path) -> None:
    expect_error(folder / "none.yaml", "none.yaml: no such file")
    (folder / "dir.yaml").mkdir()
    expect_error(folder / "dir.yaml", "dir.yaml: map YAML is a folder")
    os.mkfifo(folder / "fifo.yaml")  # opening must not block on a pipe
    expect_error(folder / "fifo.yaml", "fifo.yaml: map YAML is not a regular file")
    expect_error(Path("/dev/zero"), "/dev/zero")
    expect_error(folder / ("y" * 300 + ".yaml"), "too long")


def test_unreadable_files(folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    y = folder / "m.yaml"
    y.write_text(yaml_text())
    if os.geteuid() != 0:  # root reads anything: simulate the refusal there
        (folder / "m.pgm").chmod(0)
    else:
        real_open = os.open

        def deny(path: object, *args: object, **kw: object) -> int:
            if str(path).endswith("m.pgm"):
                raise PermissionError(13, "Permission denied", str(path))
            return real_open(path, *args, **kw)  # type: ignore[arg-type]

        monkeypatch.setattr(os, "open", deny)
    expect_error(y, "m.pgm: image file cannot be read: permission denied")


def test_keepout_yaml_goes_through_the_same_checks(folder: Path) -> None:
    y = folder / "m.yaml"
    y.write_text(yaml_text())
    k = folder / "k.yaml"
    for bad in (
        yaml_text(negate="09"),
        yaml_text(image='"k\\0.pgm"'),
        "- 1\n",
        yaml_text(resolution="1e308"),
    ):
        k.write_text(bad)
        expect_error(y, "k", keepout=k)
    k.write_text(yaml_text())
    assert len(import_ros(y, keepout=k).objects) >= 1


# -- every image variant ---------------------------------------------------------------------

BAD_IMAGES = {
    "maxval0.pgm": b"P5 3 2 0\n" + bytes(6),
    "maxval65536.pgm": b"P5 3 2 65536\n" + bytes(12),
    "maxval-huge.pgm": b"P5 3 2 " + b"9" * 5000 + b"\n" + bytes(6),
    "width-huge.pgm": b"P5 " + b"9" * 30 + b" 2 255\n" + bytes(6),
    "width-neg.pgm": b"P5 -3 2 255\n" + bytes(6),
    "width0.pgm": b"P5 0 2 255\n",
    "too-wide.pgm": b"P5 99999999 1 255\n" + bytes(10),
    "claims-huge.pgm": b"P5 40000 40000 255\n" + bytes(100),
    "truncated.pgm": PGM[:-2],
    "no-data.pgm": b"P5 3 2 255",
    "header-cut.pgm": b"P5\n3 ",
    "comment-forever.pgm": b"P5\n#" + b"c" * 70000,
    "16bit-truncated.pgm": b"P5 3 2 65535\n" + bytes(11),
    "ascii-big.pgm": b"P2 3 1 255\n0 0 " + b"9" * 25 + b"\n",
    "ascii-65bit.pgm": b"P2 3 1 255\n0 0 36893488147419103232\n",
    "ascii-over-maxval.pgm": b"P2 3 1 15\n0 0 16\n",
    "ascii-word.pgm": b"P2 3 1 255\n0 zero 1\n",
    "ascii-negative.pgm": b"P2 3 1 255\n0 -1 1\n",
    "ascii-truncated.pgm": b"P2 3 2 255\n0 1 2 3\n",
    "ascii-huge.pgm": b"P2 50000 50000 255\n0\n",
    "pbm-truncated.pbm": b"P1 3 2\n0 1 0\n",
    "p4-truncated.pbm": b"P4 9 2\n\x00",
    "ppm-truncated.ppm": b"P6 2 2 255\n" + bytes(11),
    "ppm-ascii-truncated.ppm": b"P3 1 1 255\n1 2\n",
    "empty.png": b"",
    "garbage.png": b"\x00\x01garbage" * 10,
    "bomb.png": png_bytes(40000, 40000, b"\0" * 10),
    "bomb-wide.png": png_bytes(50_000_000, 1, b"\0" * 10),
    "bomb-below-pillow.png": png_bytes(9000, 9000, b"\0" * 10),
    "truncated.png": png_bytes(64, 64, bytes(64 * 65))[:-12],
    "truncated-idat.png": png_bytes(64, 64, os.urandom(64 * 65))[:500],
    "bad-crc.png": png_bytes(4, 4, bytes(20)).replace(b"IEND\xae", b"IEND\x00"),
    "bad-idat-crc.png": png_bytes(4, 4, bytes(20))[:-16] + b"\0\0\0\0" + b"\0" * 12,
    "short-idat.png": png_bytes(64, 64, bytes(100)),
    "bad-depth.png": png_bytes(2, 2, bytes(6), depth=7),
    "palette-without-plte.png": png_bytes(2, 2, bytes(6), color=3),
}


@pytest.mark.parametrize("name", sorted(BAD_IMAGES))
@pytest.mark.parametrize("flavor", ["ros1", "nav2"])
def test_every_bad_image_is_mapkits_error_naming_it(tmp_path: Path, name: str, flavor: str) -> None:
    (tmp_path / name).write_bytes(BAD_IMAGES[name])
    y = tmp_path / "m.yaml"
    y.write_text(yaml_text(image=name))
    expect_error(y, name, flavor=flavor)
    with pytest.raises(MapkitError, match=name.replace(".", r"\.")):
        read_ros_map(y, flavor=flavor)  # type: ignore[arg-type]


def test_16_bit_pgm_is_refused_as_ros1_map_server_does_and_read_by_nav2(tmp_path: Path) -> None:
    samples = np.array([[0, 65535, 30000]], dtype=">u2")
    (tmp_path / "d.pgm").write_bytes(b"P5 3 1 65535\n" + samples.tobytes())
    (tmp_path / "a.pgm").write_bytes(b"P2 3 1 65535\n0 65535 30000\n")
    for name in ("d.pgm", "a.pgm"):
        y = tmp_path / f"{name}.yaml"
        y.write_text(yaml_text(image=name))
        expect_error(
            y, f"{name}: 16-bit PGM images (maxval 65535) fail to load in ROS 1", flavor="ros1"
        )
        assert import_ros(y, flavor="nav2").scan.num_points == 1
        assert read_ros_map(y, flavor="nav2").data.tolist() == [[100, 0, -1]]


def test_image_variants_that_load(tmp_path: Path) -> None:
    from PIL import Image

    cases = {
        "comments.pgm": b"P5\n# one\n3 # two\n# three\n2\n255\n" + PGM[-6:],
        "maxval15.pgm": b"P5 3 2 15\n" + bytes([0, 15, 12, 0, 0, 15]),
        "ascii.pgm": b"P2\n# c\n3 2\n255\n0 254\n205 0 # mid-row\n0 254\n",
        "leading-zeros.pgm": b"P2 3 2 255\n" + b"0" * 40 + b"0 254 205 0 0 254\n",
        "bits.pbm": b"P1\n3 2\n010\n111\n",
        "bits4.pbm": b"P4 3 2\n\x40\xe0",
        "colour.ppm": b"P6 3 2 255\n" + bytes([0, 0, 0] * 6),
    }
    for name, data in cases.items():
        (tmp_path / name).write_bytes(data)
    grey = np.array([[0, 254, 205], [0, 0, 254]], dtype=np.uint8)
    Image.fromarray(grey, "L").save(tmp_path / "grey.png")
    opaque = np.full_like(grey, 255)
    Image.fromarray(np.stack([grey, opaque], axis=2), "LA").save(tmp_path / "la.png")
    Image.fromarray(grey.astype(np.uint16) * 257).save(tmp_path / "deep.png")
    pal = Image.fromarray(grey, "L").convert("P")
    pal.save(tmp_path / "pal.png")
    pal.save(tmp_path / "pal-alpha.png", transparency=0)
    Image.fromarray(np.stack([grey] * 3 + [np.full_like(grey, 255)], axis=2), "RGBA").save(
        tmp_path / "rgba.png"
    )
    for name in [*cases, "grey.png", "la.png", "deep.png", "pal.png", "pal-alpha.png", "rgba.png"]:
        y = tmp_path / f"{name}.yaml"
        y.write_text(yaml_text(image=name))
        for flavor in ("ros1", "nav2"):
            m = import_ros(y, flavor=flavor)  # type: ignore[arg-type]
            assert m.scan.num_points >= 0, name
    y = tmp_path / "comments.pgm.yaml"
    assert import_ros(y).scan.num_points == 3


def test_cli_gives_one_line_and_exit_1(folder: Path) -> None:
    from click.testing import CliRunner

    from mapkit.cli.main import cli

    y = folder / "m.yaml"
    for text, says in (
        (yaml_text(negate="09"), "m.yaml:4: negate must be an integer"),
        (yaml_text(image='"m\\0.pgm"'), r"m\x00.pgm: image file name is not"),
        (yaml_text(resolution="1e308"), "reaches beyond the +-2,147,483 m"),
    ):
        y.write_text(text)
        result = CliRunner().invoke(cli, ["import-ros", str(y), "-o", str(folder / "o.map")])
        assert result.exit_code == 1, result.output
        assert result.output.count("\n") == 1 and says in result.output, result.output
        assert not (folder / "o.map").exists()


def test_grid_to_map_refuses_a_grid_beyond_arias_range() -> None:
    from mapkit.raster import OccupancyGrid
    from mapkit.raster.import_ros import grid_to_map

    wall = np.full((2, 2), 100, dtype=np.int8)
    with pytest.raises(MapkitError, match="beyond the"):
        grid_to_map(OccupancyGrid(wall, 0.05, (1e300, 0.0)))
    with pytest.raises(MapkitError, match="beyond the"):
        grid_to_map(OccupancyGrid(wall, 1e7, (0.0, 0.0)))
    assert grid_to_map(OccupancyGrid(wall, 0.05, (2e6, -2e6))).scan.num_points == 4
