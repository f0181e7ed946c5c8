"""The occupancy grid: one immutable value, laid out exactly like ROS ``nav_msgs/OccupancyGrid``.

Conventions (the same everywhere in mapkit):

* ``data`` is an ``int8`` array of shape ``(height, width)``: ``-1`` unknown, ``0`` free,
  ``100`` occupied (other values 1..99 are allowed, e.g. from a ``scale`` map or a speed mask).
* Row 0 is the **southern-most** row and column 0 the western-most: ``data[row, col]`` is the cell
  whose lower-left corner is ``origin + (col, row) * resolution``. This is ROS's order (row-major,
  x to the right, y up); images are flipped only when written to a file (north up).
* ``resolution`` is in metres per cell and ``origin`` the world position in metres of the
  lower-left corner of cell ``(0, 0)`` (ROS's ``info.origin``; the yaw is always 0).
* World coordinates in mapkit's API are millimetres (as in ARIA maps); cell indices are
  ``(row, col)`` pairs in numpy order, so ``grid.data[row, col]`` reads a cell.
* A point on a cell border belongs to the cell above/right of it (``floor``).

Examples:
    >>> import numpy as np
    >>> g = OccupancyGrid(np.zeros((3, 4), dtype=np.int8), 0.05, (-0.1, 0.0))
    >>> g.width, g.height, g.bounds_mm()
    (4, 3, ((-100.0, 0.0), (100.0, 150.0)))
    >>> g.world_to_cell([[-100, 0], [99, 149], [0, 60]]).tolist()
    [[0, 0], [2, 3], [1, 2]]
    >>> g.cell_to_world([[1, 2]]).tolist()
    [[25.0, 75.0]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["FREE", "OCCUPIED", "UNKNOWN", "OccupancyGrid"]

#: Cell values (ROS's convention).
UNKNOWN = -1
FREE = 0
OCCUPIED = 100


def _round_mm(v: float) -> float:
    """Metres to millimetres without float noise (0.05 m -> 50.0, 0.35 m -> 350.0)."""
    return round(float(v) * 1000.0, 6) + 0.0


@dataclass(frozen=True, slots=True, eq=False)
class OccupancyGrid:
    """An occupancy grid in ROS's layout (see the module docstring for the conventions).

    Attributes:
        data: ``(height, width)`` int8 array, row 0 south, read-only.
        resolution: Metres per cell (> 0).
        origin: ``(x, y)`` in metres of the lower-left corner of cell ``(0, 0)``.

    Raises:
        ValueError: For a non-2-D array, a resolution that is not a positive finite number or a
            non-finite origin.
    """

    data: NDArray[np.int8]
    resolution: float
    origin: tuple[float, float]

    def __post_init__(self) -> None:
        arr = np.asarray(self.data)
        if arr.ndim != 2:
            raise ValueError(f"an occupancy grid is 2-D, got shape {arr.shape}")
        if arr.dtype != np.int8:
            if arr.size and (arr.min() < -128 or arr.max() > 127):
                raise ValueError("occupancy values must fit in int8 (-1 unknown, 0..100)")
            arr = arr.astype(np.int8)
        elif arr.flags.writeable:
            arr = arr.copy()
        arr.flags.writeable = False
        res = float(self.resolution)
        if not (math.isfinite(res) and res > 0):
            raise ValueError(
                f"resolution must be a positive number of metres, got {self.resolution!r}"
            )
        ox, oy = (float(v) for v in self.origin)
        if not (math.isfinite(ox) and math.isfinite(oy)):
            raise ValueError(f"origin must be finite, got {self.origin!r}")
        object.__setattr__(self, "data", arr)
        object.__setattr__(self, "resolution", res)
        object.__setattr__(self, "origin", (ox + 0.0, oy + 0.0))

    # -- shape -------------------------------------------------------------------------------

    @property
    def width(self) -> int:
        """Number of columns (cells along x)."""
        return int(self.data.shape[1])

    @property
    def height(self) -> int:
        """Number of rows (cells along y)."""
        return int(self.data.shape[0])

    @property
    def resolution_mm(self) -> float:
        """Cell size in millimetres."""
        return _round_mm(self.resolution)

    @property
    def origin_mm(self) -> tuple[float, float]:
        """``origin`` in millimetres."""
        return _round_mm(self.origin[0]), _round_mm(self.origin[1])

    def bounds_mm(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The area the grid covers: ``((xmin, ymin), (xmax, ymax))`` in millimetres."""
        (ox, oy), r = self.origin_mm, self.resolution_mm
        return (ox, oy), (ox + self.width * r + 0.0, oy + self.height * r + 0.0)

    # -- coordinates -------------------------------------------------------------------------

    def world_to_cell(self, xy_mm: ArrayLike) -> NDArray[np.int64]:
        """Cell indices ``(row, col)`` of world points in millimetres (vectorised).

        Indices are not clipped: points outside the grid give indices outside
        ``[0, height) x [0, width)``; test them with :meth:`inside`.

        Args:
            xy_mm: ``(N, 2)`` (or ``(2,)``) array-like of x, y in millimetres.

        Returns:
            ``(N, 2)`` (or ``(2,)``) int64 array of ``(row, col)``.
        """
        xy = np.asarray(xy_mm, dtype=np.float64)
        (ox, oy), r = self.origin_mm, self.resolution_mm
        col = np.floor((xy[..., 0] - ox) / r)
        row = np.floor((xy[..., 1] - oy) / r)
        return np.stack([row, col], axis=-1).astype(np.int64)

    def cell_to_world(self, ij: ArrayLike) -> NDArray[np.float64]:
        """World position in millimetres of the centres of cells ``(row, col)`` (vectorised).

        Args:
            ij: ``(N, 2)`` (or ``(2,)``) array-like of ``(row, col)``.

        Returns:
            ``(N, 2)`` (or ``(2,)``) float64 array of x, y in millimetres.
        """
        rc = np.asarray(ij, dtype=np.float64)
        (ox, oy), r = self.origin_mm, self.resolution_mm
        return np.stack([ox + (rc[..., 1] + 0.5) * r, oy + (rc[..., 0] + 0.5) * r], axis=-1)

    def inside(self, ij: ArrayLike) -> NDArray[np.bool_]:
        """Which ``(row, col)`` indices lie on the grid."""
        rc = np.asarray(ij)
        return (
            (rc[..., 0] >= 0)
            & (rc[..., 0] < self.height)
            & (rc[..., 1] >= 0)
            & (rc[..., 1] < self.width)
        )

    def values_at(self, xy_mm: ArrayLike, outside: int = UNKNOWN) -> NDArray[np.int8]:
        """Cell values under world points in millimetres (``outside`` for points off the grid).

        Examples:
            >>> g = OccupancyGrid(np.array([[0, 100]], dtype=np.int8), 0.1, (0.0, 0.0))
            >>> g.values_at([[50, 50], [150, 50], [250, 50]]).tolist()
            [0, 100, -1]
        """
        rc = self.world_to_cell(np.atleast_2d(np.asarray(xy_mm, dtype=np.float64)))
        ok = self.inside(rc)
        out = np.full(len(rc), outside, dtype=np.int8)
        out[ok] = self.data[rc[ok, 0], rc[ok, 1]]
        return out

    # -- views -------------------------------------------------------------------------------

    @property
    def occupied(self) -> NDArray[np.bool_]:
        """Boolean mask of cells whose value is above 50 (ROS's "occupied" for a scale map)."""
        return self.data > 50

    @property
    def free(self) -> NDArray[np.bool_]:
        """Boolean mask of free cells (value 0)."""
        mask: NDArray[np.bool_] = self.data == FREE
        return mask

    @property
    def unknown(self) -> NDArray[np.bool_]:
        """Boolean mask of unknown cells (value -1 or any other negative value)."""
        return self.data < 0

    def with_data(self, data: ArrayLike) -> OccupancyGrid:
        """The same geometry with other cell values (same shape)."""
        arr = np.asarray(data)
        if arr.shape != self.data.shape:
            raise ValueError(f"shape {arr.shape} does not match the grid's {self.data.shape}")
        return OccupancyGrid(arr, self.resolution, self.origin)

    def same_geometry(self, other: OccupancyGrid) -> bool:
        """True when both grids have the same shape, resolution and origin."""
        return (
            self.data.shape == other.data.shape
            and self.resolution_mm == other.resolution_mm
            and self.origin_mm == other.origin_mm
        )

    def equals(self, other: object) -> bool:
        """Value equality (geometry and every cell)."""
        return (
            isinstance(other, OccupancyGrid)
            and self.same_geometry(other)
            and np.array_equal(self.data, other.data)
        )

    def __eq__(self, other: object) -> bool:
        return self.equals(other)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        counts = self.counts()
        return (
            f"OccupancyGrid({self.width}x{self.height} cells at {self.resolution:g} m, origin "
            f"({self.origin[0]:g}, {self.origin[1]:g}) m; {counts['occupied']} occupied, "
            f"{counts['free']} free, {counts['unknown']} unknown)"
        )

    def counts(self) -> dict[str, int]:
        """Number of occupied (> 50), free (0), unknown (< 0) and other cells."""
        occ = int(np.count_nonzero(self.data > 50))
        free = int(np.count_nonzero(self.data == 0))
        unk = int(np.count_nonzero(self.data < 0))
        return {
            "occupied": occ,
            "free": free,
            "unknown": unk,
            "other": int(self.data.size) - occ - free - unk,
        }

    def to_dict(self) -> dict[str, Any]:
        """Geometry and counts as JSON-ready data."""
        (x0, y0), (x1, y1) = self.bounds_mm()
        return {
            "width": self.width,
            "height": self.height,
            "resolution": self.resolution,
            "origin": [self.origin[0], self.origin[1], 0.0],
            "bounds_mm": [[x0, y0], [x1, y1]],
            **self.counts(),
        }
