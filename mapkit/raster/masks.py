"""Nav2 costmap filter masks: keepout zones and speed zones, on the same grid as the map.

* :func:`keepout_mask`: ``ForbiddenArea`` rectangles (rotated as ARIA rotates them) and
  ``ForbiddenLine`` segments are 100; every other cell is unknown (-1). Unknown, not free: Nav2's
  ``KeepoutFilter`` skips unknown mask cells but writes free ones over unknown costmap cells
  (``if (data > old_data || old_data == NO_INFORMATION)``), which would turn the map's unknown
  space free.
* :func:`speed_mask`: sectors whose type has a speed parameter (``TransVelMax`` in mm/s, as
  Omron/ARAM's ``MovementParametersSector``; 0 means "default" and is ignored) hold
  ``round(speed / multiplier)`` in 1..100; every other cell is 0, the speed filter's "no limit"
  (-1 is an error for it). Overlapping sectors take the lowest speed. The filter is Nav2's
  type 2 (absolute speed, m/s): ``speed = base + multiplier * value`` with base 0.
* :func:`filter_params_text`: the parameters file for the mask servers, the filter info servers,
  a lifecycle manager and the costmaps' ``filters``, with the node names nav2_bringup's
  ``keepout_zone_launch.py`` / ``speed_zone_launch.py`` use, so it runs unchanged.
* :func:`write_filters`: all of it next to a map's YAML: ``NAME_keepout.pgm/.yaml``,
  ``NAME_speed.pgm/.yaml`` (raw mode: the values are exact) and ``NAME_filters.yaml``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mapkit._atomic import atomic_write
from mapkit._typing import PathLike
from mapkit.formats._numbers import aria_double
from mapkit.model import MapData
from mapkit.raster.bands import DEFAULT_BAND_CELLS, Progress, band_spans, halo_rows
from mapkit.raster.errors import RasterError
from mapkit.raster.grid import OccupancyGrid
from mapkit.raster.image_stream import Bands, write_ros_map_bands
from mapkit.raster.rasterize import burn_polygons, burn_segments, inflate, object_polygons

__all__ = [
    "SPEED_PARAMS",
    "FilterFiles",
    "SpeedZone",
    "filter_params_text",
    "keepout_bands",
    "keepout_mask",
    "speed_bands",
    "speed_mask",
    "speed_zones",
    "write_filters",
]

#: Parameter names (case-insensitive) read as a sector's speed limit in mm/s.
SPEED_PARAMS = ("TransVelMax", "MaxSpeed", "SpeedLimit", "Speed", "MaxVel")

_STEPS_M_S = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)


def _unquote(tok: str) -> str:
    return tok[1:-1] if len(tok) >= 2 and tok[0] == tok[-1] == '"' else tok


def keepout_mask(
    m: MapData, like: OccupancyGrid, *, lines: bool = True, inflate_mm: float = 0.0
) -> OccupancyGrid:
    """The keepout mask: forbidden areas (and lines) 100, everything else unknown (-1).

    Args:
        m: The map.
        like: The map's grid (the mask gets its shape, resolution and origin).
        lines: Include ``ForbiddenLine`` segments (every cell they cross).
        inflate_mm: Grow the zones by this radius.

    Returns:
        The mask grid.
    """
    polys, segs = _keepout_shapes(m, lines)
    mask = burn_polygons(like, polys)
    if lines:
        burn_segments(like, segs, out=mask)
    if inflate_mm > 0:
        mask = inflate(mask, inflate_mm, like.resolution)
    data = np.where(mask, 100, -1).astype(np.int8)
    return like.with_data(data)


def _keepout_shapes(
    m: MapData, lines: bool
) -> tuple[list[NDArray[np.float64]], NDArray[np.float64]]:
    areas = [o for o in m.objects if o.type == "ForbiddenArea" and o.from_to is not None]
    segs = (
        [o.from_to for o in m.objects if o.type == "ForbiddenLine" and o.from_to is not None]
        if lines
        else []
    )
    return object_polygons(areas), np.array(segs, dtype=np.float64).reshape(-1, 4)


def _band_rows(like: OccupancyGrid, band_cells: int) -> int:
    return max(1, min(like.height, int(band_cells) // like.width))


def keepout_bands(
    m: MapData,
    like: OccupancyGrid,
    *,
    lines: bool = True,
    inflate_mm: float = 0.0,
    band_cells: int = DEFAULT_BAND_CELLS,
    progress: Progress | None = None,
) -> Bands:
    """:func:`keepout_mask` band by band, north first: ``(row0, data)`` (the same cells).

    Inflation reads a halo of rows around each band (see :mod:`mapkit.raster.bands`).
    """
    polys, segs = _keepout_shapes(m, lines)
    h, w = like.height, like.width
    halo = halo_rows(inflate_mm, like.resolution)
    for r0, r1 in band_spans(h, _band_rows(like, band_cells)):
        a, b = max(0, r0 - halo), min(h, r1 + halo)
        mask = np.zeros((b - a, w), dtype=bool)
        burn_polygons(like, polys, out=mask, row0=a)
        burn_segments(like, segs, out=mask, row0=a)
        if inflate_mm > 0:
            mask = inflate(mask, inflate_mm, like.resolution)
        if progress is not None:
            progress(r1 - r0)
        yield r0, np.where(mask[r0 - a : r1 - a], 100, -1).astype(np.int8)


@dataclass(frozen=True, slots=True)
class SpeedZone:
    """A sector with a speed limit.

    Attributes:
        name: The object's name.
        type: The object's type.
        speed_mm_s: The limit (mm/s, > 0).
        polygon: ``(4, 2)`` world corners in mm.
    """

    name: str
    type: str
    speed_mm_s: float
    polygon: NDArray[np.float64]


def _arg_descs(m: MapData) -> dict[str, list[tuple[str, str]]]:
    """Per type (lower case): its parameters' (name, default value) in ArgDesc order."""
    out: dict[str, list[tuple[str, str]]] = {}
    for line in m.info.get("MapInfo", ()):
        if not line or line[0] != "ArgDesc":
            continue
        kv: dict[str, str] = {}
        for tok in line[1:]:
            t = _unquote(tok)
            if "=" in t:
                k, v = t.split("=", 1)
                kv.setdefault(k, v)
        if "Name" in kv and "Parent" in kv:
            out.setdefault(kv["Parent"].lower(), []).append((kv["Name"], kv.get("Value", "")))
    return out


def _params(m: MapData) -> dict[str, list[str]]:
    """``CairnInfo: Params "<object>" v1 v2 ...`` by object name (lower case)."""
    out: dict[str, list[str]] = {}
    for line in m.info.get("CairnInfo", ()):
        if len(line) >= 2 and line[0] == "Params":
            out.setdefault(_unquote(line[1]).lower(), [_unquote(t) for t in line[2:]])
    return out


def speed_zones(m: MapData, *, param: str | None = None) -> list[SpeedZone]:
    """Rectangle objects whose type has a speed parameter with a value above 0.

    The value comes from the object's ``CairnInfo: Params`` line, else the ``ArgDesc``'s
    ``Value=`` default.

    Args:
        m: The map.
        param: The parameter to read (default: the first of :data:`SPEED_PARAMS` the type has).

    Returns:
        The zones, in object order.
    """
    descs = _arg_descs(m)
    params = _params(m)
    wanted = [param.lower()] if param else [p.lower() for p in SPEED_PARAMS]
    out = []
    for o in m.objects:
        if o.from_to is None or m.object_shape(o) != "rect":
            continue
        args = descs.get(o.type.lower())
        if not args:
            continue
        names = [a[0].lower() for a in args]
        index = next((names.index(w) for w in wanted if w in names), None)
        if index is None:
            continue
        values = params.get(o.name.lower(), [])
        text = values[index] if index < len(values) else args[index][1]
        speed = aria_double(text)  # a CairnInfo: value, read as ARIA reads it
        if speed is None:
            continue
        if speed > 0 and np.isfinite(speed) and o.is_finite:
            out.append(SpeedZone(o.name, o.type, speed, np.array(o.corners(), dtype=np.float64)))
    return out


def _multiplier_for(max_speed_mm_s: float) -> float:
    for step in _STEPS_M_S:
        if max_speed_mm_s <= step * 1000.0 * 100:
            return step
    raise RasterError(f"speed {max_speed_mm_s:g} mm/s is beyond what a mask can hold (100 m/s)")


def speed_mask(
    m: MapData,
    like: OccupancyGrid,
    *,
    multiplier: float | None = None,
    param: str | None = None,
    zones: list[SpeedZone] | None = None,
) -> tuple[OccupancyGrid, float]:
    """The speed mask (values 1..100 in zones, 0 elsewhere) and its multiplier in m/s.

    Args:
        m: The map.
        like: The map's grid.
        multiplier: m/s per mask unit; by default the smallest of 0.01, 0.02, 0.05, 0.1 ...
            that fits the highest speed in 100 units.
        param: The speed parameter's name (see :func:`speed_zones`).
        zones: Zones already found (default: :func:`speed_zones`).

    Returns:
        ``(mask, multiplier)``: Nav2 reads the limit as ``multiplier * value`` m/s.

    Raises:
        RasterError: For a multiplier that is not positive.
    """
    zs, multiplier = _speed_setup(m, multiplier, param, zones)
    units = np.full(like.data.shape, 127, dtype=np.int16)  # 127: no zone
    for z in zs:  # one pass per zone (a handful), vectorised over cells
        cells = burn_polygons(like, [z.polygon])
        v = int(np.clip(round(z.speed_mm_s / (multiplier * 1000.0)), 1, 100))
        units[cells] = np.minimum(units[cells], v)
    data = np.where(units == 127, 0, units).astype(np.int8)
    return like.with_data(data), float(multiplier)


def _speed_setup(
    m: MapData, multiplier: float | None, param: str | None, zones: list[SpeedZone] | None
) -> tuple[list[SpeedZone], float]:
    zs = speed_zones(m, param=param) if zones is None else zones
    if multiplier is None:
        multiplier = _multiplier_for(max((z.speed_mm_s for z in zs), default=0.0))
    if not (multiplier > 0 and np.isfinite(multiplier)):
        raise RasterError(f"speed multiplier must be a positive number of m/s, got {multiplier!r}")
    return zs, float(multiplier)


def speed_bands(
    m: MapData,
    like: OccupancyGrid,
    *,
    multiplier: float | None = None,
    param: str | None = None,
    zones: list[SpeedZone] | None = None,
    band_cells: int = DEFAULT_BAND_CELLS,
    progress: Progress | None = None,
) -> tuple[Bands, float]:
    """:func:`speed_mask` band by band, north first, and its multiplier (the same cells).

    Raises:
        RasterError: For a multiplier that is not positive (before any band is made).
    """
    zs, mult = _speed_setup(m, multiplier, param, zones)
    values = [int(np.clip(round(z.speed_mm_s / (mult * 1000.0)), 1, 100)) for z in zs]

    def bands() -> Bands:
        for r0, r1 in band_spans(like.height, _band_rows(like, band_cells)):
            units = np.full((r1 - r0, like.width), 127, dtype=np.int16)
            for z, v in zip(zs, values, strict=True):
                cells = burn_polygons(
                    like, [z.polygon], out=np.zeros(units.shape, dtype=bool), row0=r0
                )
                units[cells] = np.minimum(units[cells], v)
            if progress is not None:
                progress(r1 - r0)
            yield r0, np.where(units == 127, 0, units).astype(np.int8)

    return bands(), mult


def _q(s: str) -> str:
    import json

    return json.dumps(s, ensure_ascii=False)


def filter_params_text(
    keepout_yaml: PathLike | None,
    speed_yaml: PathLike | None = None,
    *,
    speed_multiplier: float = 0.01,
    frame_id: str = "map",
    source: str = "",
) -> str:
    """A Nav2 parameters file for the costmap filters, runnable as is.

    Sections: ``keepout_filter_mask_server`` / ``speed_filter_mask_server`` (nav2_map_server
    serving the masks), ``keepout_costmap_filter_info_server`` /
    ``speed_costmap_filter_info_server`` (type 0 keepout; type 2 absolute speed with base 0.0 and
    the multiplier), ``lifecycle_manager_costmap_filters``, and the ``filters`` of
    ``global_costmap`` and ``local_costmap``. Node names match nav2_bringup's
    ``keepout_zone_launch.py`` and ``speed_zone_launch.py``. Doubles are written with a decimal
    point (ROS 2 refuses an integer for a double parameter); mask paths are absolute.

    Raises:
        RasterError: When neither mask is given.
    """
    if keepout_yaml is None and speed_yaml is None:
        raise RasterError("a filter parameters file needs a keepout or a speed mask")
    nodes: list[str] = []
    filters: list[str] = []
    out = [
        f"# Nav2 costmap filters for {source or 'this map'}, written by mapkit.",
        "# Run with nav2_bringup (node names match its launch files), e.g.:",
    ]
    if keepout_yaml is not None:
        out.append(
            f"#   ros2 launch nav2_bringup keepout_zone_launch.py params_file:=THIS_FILE "
            f"keepout_mask:={Path(os.fspath(keepout_yaml)).resolve()}"
        )
    if speed_yaml is not None:
        out.append(
            f"#   ros2 launch nav2_bringup speed_zone_launch.py params_file:=THIS_FILE "
            f"speed_mask:={Path(os.fspath(speed_yaml)).resolve()}"
        )
    out += [
        "# or start each node with --ros-args -r __node:=NAME --params-file THIS_FILE:",
        "#   nav2_map_server map_server (the *_filter_mask_server nodes),",
        "#   nav2_map_server costmap_filter_info_server (the *_costmap_filter_info_server nodes),",
        "#   nav2_lifecycle_manager lifecycle_manager (lifecycle_manager_costmap_filters).",
        "# Add this file to Nav2's params files so the costmaps load the filters.",
    ]
    for kind, mask_yaml, ftype, mult in (
        ("keepout", keepout_yaml, 0, 1.0),
        ("speed", speed_yaml, 2, float(speed_multiplier)),
    ):
        if mask_yaml is None:
            continue
        nodes += [f"{kind}_filter_mask_server", f"{kind}_costmap_filter_info_server"]
        filters.append(f"{kind}_filter")
        out += [
            f"{kind}_filter_mask_server:",
            "  ros__parameters:",
            f"    yaml_filename: {_q(str(Path(os.fspath(mask_yaml)).resolve()))}",
            f'    topic_name: "/{kind}_filter_mask"',
            f"    frame_id: {_q(frame_id)}",
            f"{kind}_costmap_filter_info_server:",
            "  ros__parameters:",
            f"    type: {ftype}",
            f'    filter_info_topic: "/{kind}_costmap_filter_info"',
            f'    mask_topic: "/{kind}_filter_mask"',
            "    base: 0.0",
            f"    multiplier: {mult!r}",
        ]
    out += [
        "lifecycle_manager_costmap_filters:",
        "  ros__parameters:",
        "    autostart: true",
        f"    node_names: [{', '.join(_q(n) for n in nodes)}]",
    ]
    for costmap in ("global_costmap", "local_costmap"):
        # Keepout in both costmaps (as Nav2's keepout tutorial); one speed filter is enough,
        # in the global costmap (two would both publish on /speed_limit).
        names = [f for f in filters if costmap == "global_costmap" or f != "speed_filter"]
        if not names:
            continue
        out += [
            f"{costmap}:",
            f"  {costmap}:",
            "    ros__parameters:",
            f"      filters: [{', '.join(_q(f) for f in names)}]",
        ]
        if keepout_yaml is not None:
            out += [
                "      keepout_filter:",
                '        plugin: "nav2_costmap_2d::KeepoutFilter"',
                "        enabled: true",
                '        filter_info_topic: "/keepout_costmap_filter_info"',
            ]
        if "speed_filter" in names:
            out += [
                "      speed_filter:",
                '        plugin: "nav2_costmap_2d::SpeedFilter"',
                "        enabled: true",
                '        filter_info_topic: "/speed_costmap_filter_info"',
                '        speed_limit_topic: "/speed_limit"',
            ]
    return "\n".join(out) + "\n"


@dataclass(frozen=True, slots=True)
class FilterFiles:
    """What :func:`write_filters` wrote (``None`` for what it did not write)."""

    params: Path
    keepout_yaml: Path | None = None
    keepout_image: Path | None = None
    keepout_zones: int = 0
    speed_yaml: Path | None = None
    speed_image: Path | None = None
    speed_zones: int = 0
    speed_multiplier: float = 0.0


def _stem(map_yaml: Path) -> Path:
    return map_yaml.with_suffix("") if map_yaml.suffix.lower() in (".yaml", ".yml") else map_yaml


def write_filters(
    m: MapData,
    grid: OccupancyGrid,
    map_yaml: PathLike,
    *,
    keepout: bool = True,
    speed: bool = False,
    image_format: str | None = None,
    inflate_mm: float = 0.0,
    speed_param: str | None = None,
    speed_multiplier: float | None = None,
    band_cells: int = DEFAULT_BAND_CELLS,
    progress: Progress | None = None,
) -> FilterFiles:
    """Write the masks and the filter parameters file beside a map's YAML.

    ``NAME.yaml`` gets ``NAME_keepout.yaml`` + image (trinary), ``NAME_speed.yaml`` + image
    (raw) and ``NAME_filters.yaml`` (see :func:`filter_params_text`).

    Args:
        m: The map.
        grid: The map's grid (the masks use its geometry).
        map_yaml: The map's YAML path.
        keepout: Write the keepout mask.
        speed: Write the speed mask.
        image_format: ``pgm`` (default) or ``png``.
        inflate_mm: Grow keepout zones by this radius.
        speed_param: The sectors' speed parameter (see :func:`speed_zones`).
        speed_multiplier: m/s per speed-mask unit (see :func:`speed_mask`).
        band_cells: Cells per band: the masks are made and written band by band
            (:func:`keepout_bands`, :func:`speed_bands`), so a map of any size fits in memory.
        progress: Called with the rows finished (``grid.height`` per mask).

    Returns:
        The files written and the zone counts.

    Raises:
        RasterError: When neither mask is asked for.
    """
    if not (keepout or speed):
        raise RasterError("ask for a keepout mask, a speed mask or both")
    stem = _stem(Path(os.fspath(map_yaml)))
    fields: dict[str, object] = {}
    k_yaml = s_yaml = None
    if keepout:
        kbands = keepout_bands(
            m, grid, inflate_mm=inflate_mm, band_cells=band_cells, progress=progress
        )
        k = write_ros_map_bands(
            grid, kbands, Path(f"{stem}_keepout.yaml"), image_format=image_format
        )
        k_yaml = k.yaml
        zones = sum(
            1
            for o in m.objects
            if o.type in ("ForbiddenArea", "ForbiddenLine") and o.from_to is not None
        )
        fields.update(keepout_yaml=k.yaml, keepout_image=k.image, keepout_zones=zones)
    mult = 0.01
    if speed:
        zs = speed_zones(m, param=speed_param)
        sbands, mult = speed_bands(
            m, grid, multiplier=speed_multiplier, zones=zs, band_cells=band_cells, progress=progress
        )
        s = write_ros_map_bands(
            grid, sbands, Path(f"{stem}_speed.yaml"), mode="raw", image_format=image_format
        )
        s_yaml = s.yaml
        fields.update(
            speed_yaml=s.yaml, speed_image=s.image, speed_zones=len(zs), speed_multiplier=mult
        )
    params = Path(f"{stem}_filters.yaml")
    source = m.provenance.source if m.provenance else ""
    atomic_write(
        params,
        filter_params_text(
            k_yaml, s_yaml, speed_multiplier=mult, source=os.path.basename(source)
        ).encode("utf-8"),
    )
    return FilterFiles(params=params, **fields)  # type: ignore[arg-type]
