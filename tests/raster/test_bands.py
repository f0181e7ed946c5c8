"""Band-by-band rasterising and writing: the whole-grid rasteriser's cells, in bounded memory."""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import mapkit
from mapkit.model import MapData, MapObject, Scan
from mapkit.raster import OccupancyGrid, RasterError, RosMapError, rasterize
from mapkit.raster.bands import BandRaster, band_spans
from mapkit.raster.export import export_ros
from mapkit.raster.image_stream import ImageSink, write_ros_map_bands
from mapkit.raster.masks import keepout_bands, keepout_mask, speed_bands, speed_mask
from mapkit.raster.rasterize import MAX_CELLS, rays_from_log
from mapkit.raster.ros import read_ros_map, write_ros_map

from .test_masks import _speed_map

ROOT = Path(__file__).resolve().parents[2]
BUNDLED = sorted((ROOT / "mapkit" / "sample_maps").glob("*.map"))

#: (free, inflate_mm, forbidden_as_walls, resolution, margin_m)
OPTIONS = [
    ("flood", 0, False, 0.05, 0.5),
    ("hull", 0, False, 0.05, 0.5),
    ("all", 0, False, 0.05, 0.5),
    ("none", 0, False, 0.05, 0.5),
    ("flood", 120, True, 0.05, 0.5),
    ("hull", 45, True, 0.1, 0.0),
    ("flood", 0, False, 0.033, 0.2),
]


def _same_cells(m: MapData, rows: int = 5, **opts: object) -> None:
    whole = rasterize(m, **opts)  # type: ignore[arg-type]
    br = BandRaster(m, band_cells=whole.width * rows, **opts)  # type: ignore[arg-type]
    assert br.band_rows == min(rows, whole.height)
    banded = br.to_grid()
    if banded != whole:
        diff = np.argwhere(banded.data != whole.data)
        pytest.fail(f"{len(diff)} cells differ with {opts}, first at {diff[:5].tolist()}")
    assert br.counts() == whole.counts()


def _check_map(m: MapData) -> None:
    for free, inflate_mm, fw, res, margin in OPTIONS:
        _same_cells(
            m,
            free=free,
            inflate_mm=inflate_mm,
            forbidden_as_walls=fw,
            resolution=res,
            margin_m=margin,
        )


def test_bands_match_the_whole_grid_on_every_real_sample(real_sample: Path) -> None:
    _check_map(mapkit.load(real_sample))


@pytest.mark.parametrize("path", BUNDLED, ids=[p.name for p in BUNDLED])
def test_bands_match_the_whole_grid_on_the_bundled_samples(path: Path) -> None:
    _check_map(mapkit.load(path))


def test_bands_match_with_laser_rays_and_a_given_geometry() -> None:
    m = mapkit.load(ROOT / "mapkit" / "sample_maps" / "office.map")
    rays = rays_from_log(ROOT / "mapkit" / "sample_maps" / "office-loop.2d")
    _same_cells(m, rows=40, free="rays", rays_mm=rays, resolution=0.05)
    like = rasterize(m, 0.1, margin_m=2.0)
    _same_cells(m, rows=4, like=like, free="hull", inflate_mm=250)


def test_one_row_bands_and_one_band() -> None:
    m = mapkit.load(ROOT / "mapkit" / "sample_maps" / "office.map")
    _same_cells(m, rows=1, resolution=0.1, inflate_mm=100)
    _same_cells(m, rows=10_000, resolution=0.1)
    assert band_spans(7, 3) == [(4, 7), (1, 4), (0, 1)]


@st.composite
def _small_maps(draw: st.DrawFn) -> MapData:
    coord = st.integers(-3000, 3000)
    pts = draw(st.lists(st.tuples(coord, coord), max_size=40))
    lines = draw(st.lists(st.tuples(coord, coord, coord, coord), max_size=12))
    objects = [
        MapObject(draw(st.sampled_from(["Goal", "RobotHome", "Dock"])), x, y)
        for x, y in draw(st.lists(st.tuples(coord, coord), max_size=3))
    ]
    for x1, y1, x2, y2, th in draw(
        st.lists(st.tuples(coord, coord, coord, coord, st.integers(-179, 180)), max_size=3)
    ):
        objects.append(MapObject("ForbiddenArea", 0, 0, th, from_to=(x1, y1, x2, y2)))
    return MapData(
        scans=(
            Scan.from_arrays(
                np.array(pts, dtype=np.int64).reshape(-1, 2),
                np.array(lines, dtype=np.int64).reshape(-1, 4),
            ),
        ),
        objects=tuple(objects),
    )


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    m=_small_maps(),
    rows=st.integers(1, 9),
    res=st.sampled_from([0.02, 0.05, 0.07, 0.1]),
    free=st.sampled_from(["flood", "hull", "all", "none"]),
    infl=st.sampled_from([0, 30, 160]),
    fw=st.booleans(),
)
def test_bands_match_the_whole_grid_on_random_maps(
    m: MapData, rows: int, res: float, free: str, infl: int, fw: bool
) -> None:
    _same_cells(
        m,
        rows=rows,
        resolution=res,
        free=free,
        inflate_mm=infl,
        forbidden_as_walls=fw,
        margin_m=0.1,
    )


def test_masks_by_bands_match_the_whole_masks() -> None:
    m = _speed_map()
    g = rasterize(m, 0.05)
    for infl in (0, 260):
        bands = list(keepout_bands(m, g, inflate_mm=infl, band_cells=g.width * 3))
        assert len(bands) > 10
        assert np.array_equal(
            np.concatenate([b for _, b in bands[::-1]]), keepout_mask(m, g, inflate_mm=infl).data
        )
    sbands, mult = speed_bands(m, g, band_cells=g.width * 4)
    whole, mult2 = speed_mask(m, g)
    assert mult == mult2
    assert np.array_equal(np.concatenate([b for _, b in list(sbands)[::-1]]), whole.data)


def _reference_export(m: MapData, folder: Path, mode: str, fmt: str, **opts: object) -> Path:
    """The files the whole-grid path writes: rasterize + write_ros_map, masks likewise."""
    g = rasterize(m, **opts)  # type: ignore[arg-type]
    write_ros_map(g, folder / "ref.yaml", mode=mode, image_format=fmt)  # type: ignore[arg-type]
    write_ros_map(keepout_mask(m, g), folder / "ref_keepout.yaml", image_format=fmt)
    write_ros_map(speed_mask(m, g)[0], folder / "ref_speed.yaml", mode="raw", image_format=fmt)
    return folder / "ref.yaml"


@pytest.mark.parametrize(
    "mode,fmt",
    [("trinary", "pgm"), ("raw", "pgm"), ("trinary", "png"), ("scale", "png"), ("raw", "png")],
)
def test_streamed_export_writes_the_same_maps_and_masks(
    tmp_path: Path, mode: str, fmt: str
) -> None:
    m = _speed_map()
    real = ROOT.parent / "shared" / "sample-data" / "real" / "omron-ld-showroom-ex4.map"
    maps = [m] + ([mapkit.load(real)] if real.exists() else [])
    for i, mp in enumerate(maps):
        folder = tmp_path / f"{mode}-{fmt}-{i}"
        folder.mkdir()
        opts = {"resolution": 0.05, "free": "flood", "inflate_mm": 60.0}
        ref = _reference_export(mp, folder, mode, fmt, **opts)
        res = export_ros(
            mp,
            folder / "out.yaml",
            mode=mode,
            image_format=fmt,  # type: ignore[arg-type]
            keepout=True,
            speed=True,
            band_cells=1000,
            **opts,
        )  # type: ignore[arg-type]
        for stem in ("", "_keepout", "_speed"):
            a, b = folder / f"ref{stem}.yaml", folder / f"out{stem}.yaml"
            assert read_ros_map(a) == read_ros_map(b), (stem, mode, fmt)
            assert read_ros_map(a, flavor="nav2") == read_ros_map(b, flavor="nav2")
            if fmt == "pgm":
                assert a.with_suffix(".pgm").read_bytes() == b.with_suffix(".pgm").read_bytes()
            assert a.read_text().replace("ref", "out") == b.read_text()
        assert res.grid.counts() == read_ros_map(ref).counts()
        assert res.grid.to_dict() == read_ros_map(ref).to_dict()


def test_scale_pgm_with_unknown_cells_is_refused_and_leaves_nothing(tmp_path: Path) -> None:
    m = _speed_map()
    with pytest.raises(RasterError, match="needs transparency"):
        export_ros(m, tmp_path / "s.yaml", mode="scale", image_format="pgm", band_cells=500)
    assert list(tmp_path.iterdir()) == []


def test_bands_out_of_order_are_refused(tmp_path: Path) -> None:
    g = rasterize(_speed_map(), 0.1)
    south_first = [(0, g.data[:10]), (10, g.data[10:])]
    with pytest.raises(RasterError, match="out of order"):
        write_ros_map_bands(g, south_first, tmp_path / "x.yaml")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(RasterError, match="incomplete"):
        write_ros_map_bands(g, [(10, g.data[10:])], tmp_path / "x.yaml")
    with open(os.devnull, "wb") as fh, pytest.raises(RasterError, match="alpha"):
        ImageSink(fh, 3, 3, image_format="pgm", alpha=True)


_BIG = """
import json, resource, sys
from pathlib import Path

def peak_kb():
    # ru_maxrss survives fork + exec on Linux (it would report pytest's own size): read this
    # process's high-water mark, which a new program starts afresh.
    try:
        with open("/proc/self/status") as fh:
            return next(int(l.split()[1]) for l in fh if l.startswith("VmHWM:"))
    except (OSError, StopIteration):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

from mapkit.model import MapData, MapObject, Scan
from mapkit.raster.bands import BandRaster
from mapkit.raster.export import export_ros
walls = [[0, 0, 100000, 0], [100000, 0, 100000, 100000], [100000, 100000, 0, 100000],
         [0, 100000, 0, 0], [50000, 0, 50000, 60000]]
m = MapData(scans=(Scan.from_arrays(points=[[25000, 25000]], lines=walls),),
            objects=(MapObject("RobotHome", 10000, 10000),
                     MapObject("ForbiddenArea", 0, 0, 30, from_to=(60000, 60000, 70000, 65000))))
res = export_ros(m, Path(sys.argv[1]) / "big.yaml", resolution=0.01, margin_m=0.05, keepout=True,
                 band_cells=1_000_000, progress=lambda d, t: None)
br = BandRaster(m, 0.01, margin_m=0.05, band_cells=1_000_000)
print(json.dumps({"width": res.grid.width, "height": res.grid.height, "counts": res.grid.counts(),
                  "band_bytes": br.band_bytes(), "band_rows": br.band_rows,
                  "maxrss_kb": peak_kb()}))
"""


def test_a_map_above_the_old_limit_is_written_in_bounded_memory(tmp_path: Path) -> None:
    """A 100 x 100 m room at 1 cm: 100.2 M cells, over the old 100 M refusal, in a subprocess."""
    out = subprocess.run(
        [sys.executable, "-c", _BIG, str(tmp_path)],
        capture_output=True,
        text=True,
        check=True,
        cwd=ROOT,
    )
    r = json.loads(out.stdout)
    w, h = r["width"], r["height"]
    assert w * h > MAX_CELLS
    assert r["band_rows"] * w <= 1_000_000 and r["band_bytes"] < 25_000_000
    # The whole-grid path would hold a 100 MB int8 grid plus bool and int32 masks of the same
    # shape (over 700 MB); banded, the process holds one band at a time: about 100 MB measured,
    # most of it Python, numpy and scipy themselves.
    assert r["maxrss_kb"] < 200_000, r
    assert r["counts"]["free"] > 99_000_000 and r["counts"]["occupied"] > 40_000
    pgm = tmp_path / "big.pgm"
    header = f"P5\n# CREATOR: mapkit 0.010 m/pix\n{w} {h}\n255\n".encode()
    assert pgm.read_bytes()[: len(header)] == header
    img = np.memmap(pgm, dtype=np.uint8, mode="r", offset=len(header), shape=(h, w))
    row = np.asarray(img[h // 2])  # the middle row, north up: margin, wall, room, wall, room, wall
    walls = np.flatnonzero(row == 0)
    assert len(walls) == 3 and set(row[walls[0] + 1 : walls[-1]].tolist()) == {0, 254}
    assert set(row[: walls[0]].tolist()) == {205}
    keep = np.memmap(
        tmp_path / "big_keepout.pgm", dtype=np.uint8, mode="r", offset=len(header), shape=(h, w)
    )
    zone = sum(
        int(np.count_nonzero(np.asarray(keep[i : i + 1000]) == 0)) for i in range(0, h, 1000)
    )
    assert 500_000 <= zone <= 505_000  # the 10 x 5 m forbidden area at 1 cm, and its outline


def test_rasterize_makes_grids_over_max_cells_by_bands(monkeypatch: pytest.MonkeyPatch) -> None:
    rasterize_module = sys.modules["mapkit.raster.rasterize"]  # the package names the function
    m = mapkit.load(ROOT / "mapkit" / "sample_maps" / "office.map")
    whole = rasterize(m, 0.05, inflate_mm=100)
    calls: list[int] = []
    real = BandRaster.to_grid

    def spy(self: BandRaster, progress: object = None) -> object:
        calls.append(self.grid.width * self.grid.height)
        return real(self, progress)  # type: ignore[arg-type]

    monkeypatch.setattr(rasterize_module, "MAX_CELLS", 10_000)
    monkeypatch.setattr(BandRaster, "to_grid", spy)
    banded = rasterize(m, 0.05, inflate_mm=100)
    assert calls == [whole.width * whole.height] and banded == whole
    assert not banded.data.flags.writeable


def test_a_map_too_large_for_ros1_is_said_before_the_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from mapkit.raster import export
    from mapkit.raster.export import consumer_warnings

    assert consumer_warnings(20_805, 13_555) == []  # the 282 M-cell site fits a ROS 1 message
    [text] = consumer_warnings(41_609, 27_109)  # the same site at 1 cm does not
    assert "1,127,978,381 cells" in text and "1,000,000,000 bytes" in text
    monkeypatch.setattr(export, "ROS1_MAX_CELLS", 1000)
    events: list[str] = []
    export_ros(
        _speed_map(),
        tmp_path / "s.yaml",
        warn=lambda t: events.append("warn: " + t),
        progress=lambda d, t: events.append("progress"),
    )
    assert events[0].startswith("warn: a 221 x 181 map (40,001 cells) is too large for ROS 1")
    assert events[1:] and set(events[1:]) == {"progress"}


def _png_chunks(data: bytes) -> list[bytes]:
    kinds, pos = [], 8
    while pos < len(data):
        n = int.from_bytes(data[pos : pos + 4], "big")
        kinds.append(data[pos + 4 : pos + 8])
        pos += 12 + n
    return kinds


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    h=st.integers(1, 30),
    w=st.integers(1, 30),
    seed=st.integers(0, 2**32 - 1),
    cuts=st.lists(st.integers(1, 29), max_size=5),
    mode=st.sampled_from(["trinary", "scale", "raw"]),
    fmt=st.sampled_from(["pgm", "png"]),
)
def test_any_band_split_round_trips(
    tmp_path_factory: pytest.TempPathFactory,
    monkeypatch: pytest.MonkeyPatch,
    h: int,
    w: int,
    seed: int,
    cuts: list[int],
    mode: str,
    fmt: str,
) -> None:
    from mapkit.raster import image_stream

    monkeypatch.setattr(image_stream, "IDAT_BYTES", 16)  # many IDAT chunks
    rng = np.random.default_rng(seed)
    values = np.array([-1, 0, 100, 35, 70] if mode != "trinary" else [-1, 0, 100], dtype=np.int8)
    if fmt == "pgm" and mode == "scale":
        values = values[values >= 0]  # a scale PGM has no transparency for unknown cells
    g = OccupancyGrid(rng.choice(values, size=(h, w)), 0.05, (-1.0, 2.5))
    edges = sorted({0, h, *[c for c in cuts if c < h]})
    bands = [(a, g.data[a:b]) for a, b in itertools.pairwise(edges)][::-1]
    folder = tmp_path_factory.mktemp("split")
    files = write_ros_map_bands(
        g,
        bands,
        folder / "m.yaml",
        mode=mode,  # type: ignore[arg-type]
        image_format=fmt,
    )
    ref = write_ros_map(g, folder / "ref.yaml", mode=mode, image_format=fmt)  # type: ignore[arg-type]
    for flavor in ("ros1", "nav2"):
        back = read_ros_map(files.yaml, flavor=flavor)  # type: ignore[arg-type]
        assert back == read_ros_map(ref.yaml, flavor=flavor)  # type: ignore[arg-type]
        if mode != "scale":  # scale mode gives the nearest level a loader reads, not always exact
            assert back == g
    if fmt == "pgm":
        assert files.image.read_bytes() == ref.image.read_bytes()
    else:
        kinds = _png_chunks(files.image.read_bytes())
        assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND" and set(kinds[1:-1]) == {b"IDAT"}


def test_a_png_in_many_idat_chunks_reads_back(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from mapkit.raster import image_stream

    monkeypatch.setattr(image_stream, "IDAT_BYTES", 2048)
    rng = np.random.default_rng(7)
    g = OccupancyGrid(
        rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(600, 700)), 0.05, (0.0, 0.0)
    )
    bands = [(r0, g.data[r0:r1]) for r0, r1 in band_spans(600, 37)]
    files = write_ros_map_bands(g, bands, tmp_path / "noise.yaml", image_format="png")
    kinds = _png_chunks(files.image.read_bytes())
    assert kinds.count(b"IDAT") > 2 and kinds[-1] == b"IEND"
    assert read_ros_map(files.yaml) == g and read_ros_map(files.yaml, flavor="nav2") == g


@pytest.mark.parametrize(
    "mode,negate,occ,free",
    [
        ("trinary", False, 0.65, 0.196),
        ("trinary", True, 0.65, 0.196),
        ("trinary", False, 0.9, 0.1),
        ("raw", False, 0.65, 0.196),
        ("scale", False, 0.65, 0.196),
    ],
)
def test_pgm_read_by_bands_is_read_ros_map(
    tmp_path: Path, mode: str, negate: bool, occ: float, free: float
) -> None:
    from mapkit.raster.image_stream import pgm_bands
    from mapkit.raster.ros import read_ros_yaml

    g = rasterize(_speed_map(), 0.05, inflate_mm=80)
    if mode == "scale":  # a scale PGM holds no unknown cells; use in-between values instead
        g = g.with_data(np.where(g.data < 0, 40, g.data))
    elif mode == "raw":
        g = g.with_data(np.where(g.data == 0, 17, g.data))
    files = write_ros_map(
        g,
        tmp_path / "m.yaml",
        mode=mode,
        image_format="pgm",  # type: ignore[arg-type]
        negate=negate,
        occupied_thresh=occ,
        free_thresh=free,
    )
    for flavor in ("ros1", "nav2"):
        pgm = pgm_bands(read_ros_yaml(files.yaml, flavor=flavor), flavor=flavor)  # type: ignore[arg-type]
        assert pgm is not None
        whole = read_ros_map(files.yaml, flavor=flavor)  # type: ignore[arg-type]
        assert pgm.to_grid(band_cells=pgm.width * 3) == whole
        assert pgm.geometry().same_geometry(whole)


def test_pgm_bands_leaves_other_images_to_the_whole_reader(tmp_path: Path) -> None:
    from mapkit.raster.image_stream import pgm_bands
    from mapkit.raster.ros import read_ros_map, read_ros_yaml

    g = rasterize(_speed_map(), 0.1)
    png = write_ros_map(g, tmp_path / "p.yaml", image_format="png")
    assert pgm_bands(read_ros_yaml(png.yaml)) is None
    pgm = write_ros_map(g, tmp_path / "q.yaml")
    data = pgm.image.read_bytes()
    pgm.image.write_bytes(data[:-10])  # truncated
    with pytest.raises(RosMapError, match=r"q\.pgm: image data truncated"):
        pgm_bands(read_ros_yaml(pgm.yaml))
    pgm.image.write_bytes(data.replace(b"\n255\n", b"\n254\n", 1))  # any binary PNM streams
    bands = pgm_bands(read_ros_yaml(pgm.yaml))
    assert bands is not None
    assert bands.to_grid(band_cells=bands.width * 2) == read_ros_map(pgm.yaml)


@pytest.mark.parametrize("mode,fmt", [("trinary", "pgm"), ("scale", "png")])
def test_streamed_files_equal_on_every_real_sample(
    real_sample: Path, tmp_path: Path, mode: str, fmt: str
) -> None:
    m = mapkit.load(real_sample)
    opts = {"resolution": 0.05, "free": "flood", "inflate_mm": 100.0}
    ref = _reference_export(m, tmp_path, mode, fmt, **opts)
    export_ros(
        m,
        tmp_path / "out.yaml",
        mode=mode,
        image_format=fmt,  # type: ignore[arg-type]
        keepout=True,
        speed=True,
        band_cells=20_000,
        **opts,
    )  # type: ignore[arg-type]
    for stem in ("", "_keepout", "_speed"):
        a, b = tmp_path / f"ref{stem}.yaml", tmp_path / f"out{stem}.yaml"
        if fmt == "pgm":
            assert a.with_suffix(".pgm").read_bytes() == b.with_suffix(".pgm").read_bytes(), stem
        assert read_ros_map(a) == read_ros_map(b), stem
    assert ref.exists()
