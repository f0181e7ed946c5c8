"""Write map_server images of any size band by band: PGM rows as they come, PNG deflated by band.

:func:`write_ros_map_bands` is :func:`~mapkit.raster.ros.write_ros_map` for a grid that arrives
as bands of rows (north first, e.g. from :meth:`~mapkit.raster.bands.BandRaster.bands`): each
band goes through the same pixel table (:func:`~mapkit.raster.ros.pixel_table`) and is written at
once, so only one band is ever in memory. The PNG is written chunk by chunk: one zlib stream fed
row band by row band (filter type 0 on every row, as the whole-image writer), cut into ``IDAT``
chunks of about 1 MB. Both files are written atomically: a failure half-way leaves the old file.

In ``scale`` mode a PNG always has an alpha channel (unknown cells are transparent; whether the
grid has any is only known at the end); a ``scale`` PGM fails at the first unknown cell, and
nothing is written.

Examples:
    >>> import tempfile, pathlib
    >>> from mapkit.raster.ros import read_ros_map
    >>> g = OccupancyGrid(np.array([[0, 100, -1], [-1, 0, 0]], dtype=np.int8), 0.05, (0.0, 0.0))
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "room.yaml"
    >>> files = write_ros_map_bands(g, [(1, g.data[1:]), (0, g.data[:1])], out, image_format="png")
    >>> read_ros_map(out) == g
    True
"""

from __future__ import annotations

import os
import struct
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np
from numpy.typing import NDArray

from mapkit._atomic import atomic_open
from mapkit._typing import PathLike
from mapkit.raster.errors import RasterError
from mapkit.raster.grid import OccupancyGrid
from mapkit.raster.ros import (
    DEFAULT_FREE_THRESH,
    DEFAULT_OCCUPIED_THRESH,
    Flavor,
    Mode,
    RosMapFiles,
    RosMapInfo,
    check_scale,
    image_target,
    open_map_image,
    pgm_comment,
    pixel_table,
    pixel_values,
    write_map_yaml,
)
from mapkit.raster.ros_image import ImageSource

__all__ = [
    "IDAT_BYTES",
    "ImageSink",
    "PgmBands",
    "pgm_bands",
    "write_image_bands",
    "write_ros_map_bands",
]

#: About how many compressed bytes go in one PNG ``IDAT`` chunk.
IDAT_BYTES = 1 << 20

#: Bands of a grid, north first: ``(row0, data)``, ``data[0]`` being grid row ``row0``.
Bands = Iterable[tuple[int, NDArray[np.int8]]]


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


class ImageSink:
    """Writes a grey (or grey + alpha) image top row first into an open binary file.

    Args:
        fh: The file.
        width: Pixels per row.
        height: Rows.
        image_format: ``pgm`` or ``png``.
        alpha: PNG only: rows carry an alpha channel.
        comment: The PGM header comment.
        level: zlib level for PNG (6, as the whole-image writer).
    """

    def __init__(
        self,
        fh: BinaryIO,
        width: int,
        height: int,
        *,
        image_format: str,
        alpha: bool = False,
        comment: str = "CREATOR: mapkit",
        level: int = 6,
    ) -> None:
        if image_format not in ("pgm", "png"):
            raise RasterError(f"image format must be pgm or png, got {image_format!r}")
        if alpha and image_format == "pgm":
            raise RasterError("PGM has no alpha channel; use PNG")
        self.fh, self.width, self.height = fh, int(width), int(height)
        self.format, self.alpha = image_format, alpha
        self.rows_written = 0
        self._pending: list[bytes] = []
        self._pending_len = 0
        if image_format == "pgm":
            fh.write(f"P5\n# {comment}\n{self.width} {self.height}\n255\n".encode("ascii"))
        else:
            self._z = zlib.compressobj(level)
            ihdr = struct.pack(">IIBBBBB", self.width, self.height, 8, 4 if alpha else 0, 0, 0, 0)
            fh.write(b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr))

    def write_rows(self, grey: NDArray[np.uint8], alpha: NDArray[np.uint8] | None = None) -> None:
        """Append rows, top first: ``grey`` ``(k, width)``, and ``alpha`` when the image has it."""
        k = grey.shape[0]
        if grey.shape != (k, self.width) or self.rows_written + k > self.height:
            raise RasterError(
                f"rows of shape {grey.shape} do not fit a {self.width} x "
                f"{self.height} image with {self.rows_written} rows written"
            )
        if (alpha is not None) != self.alpha:
            raise RasterError("give alpha exactly when the image has an alpha channel")
        self.rows_written += k
        if self.format == "pgm":
            self.fh.write(np.ascontiguousarray(grey).tobytes())
            return
        bpp = 2 if alpha is not None else 1
        raw = np.zeros((k, self.width * bpp + 1), dtype=np.uint8)  # filter byte 0 per row
        if alpha is not None:
            raw[:, 1::2] = grey
            raw[:, 2::2] = alpha
        else:
            raw[:, 1:] = grey
        self._emit(self._z.compress(raw.tobytes()))

    def _emit(self, data: bytes, final: bool = False) -> None:
        if data:
            self._pending.append(data)
            self._pending_len += len(data)
        if self._pending_len >= IDAT_BYTES or (final and self._pending_len):
            self.fh.write(_chunk(b"IDAT", b"".join(self._pending)))
            self._pending, self._pending_len = [], 0

    def close(self) -> None:
        """Finish the image (checks every row was written)."""
        if self.rows_written != self.height:
            raise RasterError(f"image incomplete: {self.rows_written} of {self.height} rows")
        if self.format == "png":
            self._emit(self._z.flush(), final=True)
            self.fh.write(_chunk(b"IEND", b""))


def write_image_bands(
    path: PathLike,
    geometry: OccupancyGrid,
    bands: Bands,
    lut: NDArray[np.uint8],
    opaque: NDArray[np.bool_] | None = None,
    *,
    image_format: str,
    comment: str = "CREATOR: mapkit",
) -> None:
    """Write bands of cells as an image through a pixel table, north up, atomically.

    Args:
        path: The image file.
        geometry: The grid's geometry (width, height).
        bands: The cells, north band first, contiguous.
        lut: Grey level by ``value & 0xFF``.
        opaque: Opacity by ``value & 0xFF``; with any ``False`` a PNG gets an alpha channel and a
            PGM refuses transparent cells.
        image_format: ``pgm`` or ``png``.
        comment: PGM header comment.

    Raises:
        RasterError: For bands out of order, or a transparent cell in a PGM (nothing is written).
    """
    w, h = geometry.width, geometry.height
    transparent = opaque is not None and not bool(opaque.all())
    use_alpha = transparent and image_format == "png"
    with atomic_open(path) as fh:
        sink = ImageSink(fh, w, h, image_format=image_format, alpha=use_alpha, comment=comment)
        expect = h
        for r0, band in bands:
            if r0 + len(band) != expect or band.shape[1:] != (w,):
                raise RasterError(
                    f"band of rows {r0}..{r0 + len(band)} out of order (next "
                    f"expected to end at row {expect})"
                )
            expect = r0
            idx = band[::-1].view(np.uint8)
            alpha = None
            if transparent and opaque is not None:
                clear = ~opaque[idx]
                if not use_alpha and clear.any():
                    raise RasterError(
                        "scale mode with unknown cells needs transparency: write PNG, not PGM"
                    )
                if use_alpha:
                    alpha = np.where(clear, 0, 255).astype(np.uint8)
            sink.write_rows(lut[idx], alpha)
        sink.close()


def write_ros_map_bands(
    geometry: OccupancyGrid,
    bands: Bands,
    yaml_path: PathLike,
    *,
    mode: Mode = "trinary",
    image_format: str | None = None,
    image_path: PathLike | None = None,
    negate: bool = False,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
) -> RosMapFiles:
    """Write a grid given as bands as a map_server map: the image, then the YAML (both atomic).

    The same files as :func:`~mapkit.raster.ros.write_ros_map` for the same cells (see the module
    docstring for ``scale`` mode). Options are checked before anything is written.

    Args:
        geometry: The grid's geometry (its cells are not read).
        bands: The cells, north band first (see :data:`Bands`).
        yaml_path: The YAML file.
        mode: ``trinary``, ``scale`` or ``raw``.
        image_format: ``pgm`` or ``png`` (default from ``mode`` or ``image_path``, as
            ``write_ros_map``).
        image_path: The image file (default beside the YAML).
        negate: Inverted grey levels and ``negate: 1``.
        occupied_thresh: The YAML's ``occupied_thresh``.
        free_thresh: The YAML's ``free_thresh``.

    Returns:
        The paths written.
    """
    yaml_p = Path(os.fspath(yaml_path))
    lut, opaque = pixel_table(mode, negate, occupied_thresh, free_thresh)
    img_p, fmt = image_target(yaml_p, mode, image_format, image_path)
    if mode == "scale":
        bands = _scale_checked(bands, lut, negate, occupied_thresh, free_thresh)
    write_image_bands(
        img_p, geometry, bands, lut, opaque, image_format=fmt, comment=pgm_comment(geometry)
    )
    write_map_yaml(
        yaml_p,
        img_p,
        geometry,
        mode=mode,
        negate=negate,
        occupied_thresh=occupied_thresh,
        free_thresh=free_thresh,
    )
    return RosMapFiles(yaml_p, img_p)


def _scale_checked(
    bands: Bands, lut: NDArray[np.uint8], negate: bool, occupied_thresh: float, free_thresh: float
) -> Bands:
    """The bands unchanged, counted; after the last, :func:`check_scale` on the whole count.

    It runs inside the image's atomic write, so a refusal leaves nothing written.
    """
    counts = np.zeros(256, dtype=np.int64)
    for r0, band in bands:
        counts += np.bincount(band.view(np.uint8).ravel(), minlength=256)
        yield r0, band
    check_scale(counts, lut, negate, occupied_thresh, free_thresh)


@dataclass(frozen=True, slots=True)
class PgmBands:
    """A map YAML's binary PNM image read band by band (see :func:`pgm_bands`)."""

    info: RosMapInfo
    source: ImageSource  # a streamed (binary PNM) image, header already checked
    flavor: Flavor

    @property
    def width(self) -> int:
        """Pixels per row."""
        return self.source.width

    @property
    def height(self) -> int:
        """Rows."""
        return self.source.height

    def geometry(self) -> OccupancyGrid:
        """The grid's geometry (its cells are not read)."""
        cells = np.broadcast_to(np.array(-1, dtype=np.int8), (self.height, self.width))
        return OccupancyGrid(cells, self.info.resolution, self.info.origin[:2])

    def bands(self, band_cells: int = 4_000_000) -> Iterator[tuple[int, NDArray[np.int8]]]:
        """The cells, north band first: ``(row0, data)`` as :meth:`BandRaster.bands` gives."""
        w, h = self.width, self.height
        rows = max(1, min(h, band_cells // max(w, 1)))
        r1 = h
        while r1 > 0:
            r0 = max(0, r1 - rows)
            img = self.source.read_rows(h - r1, h - r0)  # image rows run north to south
            cells = pixel_values(img, self.info, flavor=self.flavor)
            yield r0, np.ascontiguousarray(cells[::-1])
            r1 = r0

    def to_grid(self, band_cells: int = 4_000_000) -> OccupancyGrid:
        """The whole grid (one byte a cell), read a band at a time."""
        data = np.empty((self.height, self.width), dtype=np.int8)
        for r0, band in self.bands(band_cells):
            data[r0 : r0 + len(band)] = band
        data.flags.writeable = False
        return OccupancyGrid(data, self.info.resolution, self.info.origin[:2])


def pgm_bands(info: RosMapInfo, *, flavor: Flavor = "ros1") -> PgmBands | None:
    """A map YAML's image as bands of cells, when it is a binary PNM (read from the file on demand).

    The image is opened and checked as :func:`~mapkit.raster.ros.open_map_image` does, and each
    band's pixels go through :func:`~mapkit.raster.ros.pixel_values`, the loaders' own rules, so
    the cells are ``read_ros_map``'s; only a band of the image is in memory at a time. ``None``
    for an image that is decoded whole (PNG, ASCII PNM: read it with ``read_ros_map``).

    Raises:
        RosMapError: For an image the loader refuses, naming the file.
    """
    source = open_map_image(info, flavor=flavor)
    return PgmBands(info, source, flavor) if source.streamed else None
