"""One call from an ARIA map to a ROS map bundle, and the ``.yaml``/``.pgm`` formats for convert.

:func:`export_ros` rasterises a map and writes the map_server files (and optionally the Nav2
keepout/speed masks and their parameters file); it is what ``mapkit rasterize`` runs. It works
band by band (:mod:`mapkit.raster.bands`, :mod:`mapkit.raster.image_stream`): a map of any extent
is written in memory that grows with the band, not with the map, and the cells are those of
:func:`~mapkit.raster.rasterize.rasterize`. Importing this module registers the
``.yaml``/``.pgm`` writers and the ``.yaml`` reader in
:mod:`mapkit.formats.registry`, so ``mapkit convert office.map office.yaml`` and
``mapkit convert office.yaml office.map`` work.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mapkit._typing import PathLike
from mapkit.formats.registry import register_reader, register_writer
from mapkit.model import MapData
from mapkit.raster.bands import DEFAULT_BAND_CELLS, BandRaster, GridInfo
from mapkit.raster.image_stream import write_ros_map_bands
from mapkit.raster.import_ros import import_ros
from mapkit.raster.masks import FilterFiles, write_filters
from mapkit.raster.rasterize import FreeMode
from mapkit.raster.ros import Mode, RosMapFiles

__all__ = [
    "EXPORT_STEPS",
    "ROS1_MAX_CELLS",
    "ROS1_MAX_MESSAGE_BYTES",
    "ExportProgress",
    "RosExport",
    "consumer_warnings",
    "export_ros",
    "planned_outputs",
]

#: roscpp drops any message longer than this (bytes; ros_comm's ``TransportPublisherLink::
#: onMessageLength`` and ``ServiceServerLink``: "a message of over a gigabyte was predicted").
ROS1_MAX_MESSAGE_BYTES = 1_000_000_000
#: The most cells a ``nav_msgs/OccupancyGrid`` can carry to a roscpp node (one byte a cell; 1 KiB
#: left for its header, frame id and ``MapMetaData``).
ROS1_MAX_CELLS = ROS1_MAX_MESSAGE_BYTES - 1024


def consumer_warnings(width: int, height: int) -> list[str]:
    """What cannot take a ``width`` x ``height`` map_server map (empty when everything can).

    ROS 1's map_server loads any image but publishes it as one ``nav_msgs/OccupancyGrid``, which
    every roscpp node drops when it is over :data:`ROS1_MAX_MESSAGE_BYTES`.
    """
    cells = int(width) * int(height)
    if cells <= ROS1_MAX_CELLS:
        return []
    return [
        f"a {width} x {height} map ({cells:,} cells) is too large for ROS 1: map_server "
        f"publishes it as one nav_msgs/OccupancyGrid of about {cells / 1e9:.2f} GB, and every "
        f"roscpp node (rviz, move_base, amcl) drops messages over "
        f"{ROS1_MAX_MESSAGE_BYTES:,} bytes (at most {ROS1_MAX_CELLS:,} cells); the files are "
        f"written all the same"
    ]


#: The stages of :func:`export_ros`, in order.
EXPORT_STEPS = ("rasterise", "write map", "write masks")

#: ``progress(done, total)``: ``done`` of ``total`` rows of work are finished (the map's rows
#: once per pass of the rasteriser, and once per mask).
ExportProgress = Callable[[int, int], None]


@dataclass(frozen=True, slots=True)
class RosExport:
    """What :func:`export_ros` made.

    ``grid`` is the written grid's geometry and cell counts (:class:`GridInfo`: the cells
    themselves are in the image; read them back with :func:`~mapkit.raster.ros.read_ros_map`).
    """

    grid: GridInfo
    map_files: RosMapFiles
    filters: FilterFiles | None = None
    mode: str = "trinary"

    def files(self) -> list[Path]:
        """Every file written, in order."""
        out = [self.map_files.image, self.map_files.yaml]
        f = self.filters
        if f is not None:
            out += [
                p
                for p in (f.keepout_image, f.keepout_yaml, f.speed_image, f.speed_yaml, f.params)
                if p is not None
            ]
        return out

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        out: dict[str, Any] = {
            "yaml": str(self.map_files.yaml),
            "image": str(self.map_files.image),
            "mode": self.mode,
            "grid": self.grid.to_dict(),
        }
        f = self.filters
        if f is not None:
            out["filters"] = {
                "params": str(f.params),
                "keepout_yaml": None if f.keepout_yaml is None else str(f.keepout_yaml),
                "keepout_zones": f.keepout_zones,
                "speed_yaml": None if f.speed_yaml is None else str(f.speed_yaml),
                "speed_zones": f.speed_zones,
                "speed_multiplier": f.speed_multiplier if f.speed_yaml is not None else None,
            }
        return out


def _stem(yaml_path: Path) -> Path:
    return yaml_path.with_suffix("") if yaml_path.suffix.lower() in (".yaml", ".yml") else yaml_path


def planned_outputs(
    yaml_path: PathLike,
    *,
    image_format: str = "pgm",
    keepout: bool = False,
    speed: bool = False,
) -> list[Path]:
    """The files :func:`export_ros` will write for these options (to check before writing)."""
    y = Path(os.fspath(yaml_path))
    stem = _stem(y)
    out = [y.with_suffix("." + image_format), y]
    if keepout:
        out += [Path(f"{stem}_keepout.{image_format}"), Path(f"{stem}_keepout.yaml")]
    if speed:
        out += [Path(f"{stem}_speed.{image_format}"), Path(f"{stem}_speed.yaml")]
    if keepout or speed:
        out.append(Path(f"{stem}_filters.yaml"))
    return out


def export_ros(
    m: MapData,
    yaml_path: PathLike,
    *,
    resolution: float = 0.05,
    margin_m: float = 0.5,
    free: FreeMode = "flood",
    inflate_mm: float = 0.0,
    forbidden_as_walls: bool = False,
    mode: Mode = "trinary",
    image_format: str | None = None,
    keepout: bool = False,
    speed: bool = False,
    speed_param: str | None = None,
    progress: ExportProgress | None = None,
    log: Any = None,
    band_cells: int = DEFAULT_BAND_CELLS,
    warn: Callable[[str], None] | None = None,
) -> RosExport:
    """Rasterise a map and write it as a map_server map (plus Nav2 masks on request).

    Args:
        m: The map.
        yaml_path: ``NAME.yaml``; the image is ``NAME.pgm`` (or ``.png``) beside it.
        resolution: Metres per cell.
        margin_m: Unknown border around the map, metres.
        free: Free-space mode (see :func:`~mapkit.raster.rasterize.rasterize`).
        inflate_mm: Grow walls by this radius.
        forbidden_as_walls: Draw forbidden areas and lines as walls in the map itself.
        mode: ``trinary``, ``scale`` or ``raw`` (see :func:`~mapkit.raster.ros.write_ros_map`).
        image_format: ``pgm`` (default) or ``png``.
        keepout: Also write ``NAME_keepout`` and ``NAME_filters.yaml``.
        speed: Also write ``NAME_speed`` and ``NAME_filters.yaml``.
        speed_param: Sector parameter holding the speed (default ``TransVelMax`` and friends).
        progress: Called as ``progress(done, total)`` as rows are finished (see
            :data:`ExportProgress`).
        log: A ``.2d`` laser log whose beams give the free space.
        band_cells: About how many cells are worked on at once (see
            :class:`~mapkit.raster.bands.BandRaster`).
        warn: Called, before any work, with each of :func:`consumer_warnings` (a map too large
            for a ROS 1 message).

    Returns:
        The grid's geometry and counts and the files written.

    Raises:
        RasterError: For bad options (before anything is written).
    """
    raster = BandRaster(
        m,
        resolution,
        margin_m=margin_m,
        free=free,
        inflate_mm=inflate_mm,
        log=log,
        forbidden_as_walls=forbidden_as_walls,
        band_cells=band_cells,
    )
    geometry = raster.grid
    if warn is not None:
        for message in consumer_warnings(geometry.width, geometry.height):
            warn(message)
    total = raster.work_rows + geometry.height * (int(keepout) + int(speed))
    done = 0

    def step(rows: int) -> None:
        nonlocal done
        done += rows
        if progress is not None:
            progress(done, total)

    files = write_ros_map_bands(
        geometry, raster.bands(step), yaml_path, mode=mode, image_format=image_format
    )
    filters = None
    if keepout or speed:
        fmt = files.image.suffix.lstrip(".").lower()
        filters = write_filters(
            m,
            geometry,
            files.yaml,
            keepout=keepout,
            speed=speed,
            image_format=fmt,
            speed_param=speed_param,
            band_cells=band_cells,
            progress=step,
        )
    return RosExport(raster.info(), files, filters, mode)


def _write_yaml(m: MapData, path: PathLike) -> str:
    res = export_ros(m, path)
    g = res.grid
    return (
        f"wrote {res.map_files.yaml} and {res.map_files.image} ({g.width}x{g.height} cells at "
        f"{g.resolution:g} m)"
    )


def _write_pgm(m: MapData, path: PathLike) -> str:
    p = Path(os.fspath(path))
    y = p.with_suffix(".yaml")
    raster = BandRaster(m)
    grid = raster.grid
    files = write_ros_map_bands(grid, raster.bands(), y, image_path=p)
    return (
        f"wrote {files.image} and {files.yaml} ({grid.width}x{grid.height} cells at "
        f"{grid.resolution:g} m)"
    )


register_writer(".yaml", _write_yaml)
register_writer(".yml", _write_yaml)
register_writer(".pgm", _write_pgm)
register_reader(".yaml", import_ros)
register_reader(".yml", import_ros)
