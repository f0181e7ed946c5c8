"""What the ROS loaders (map_server, nav2_map_server) make of a pixel."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from mapkit.raster.errors import RasterError
from mapkit.raster.ros.common import DEFAULT_FREE_THRESH, DEFAULT_OCCUPIED_THRESH, MODES, Flavor

__all__ = ["load_pixel_values"]


# -- what the loaders make of a pixel ------------------------------------------------------------


def load_pixel_values(
    grey: NDArray[Any],
    mode: str,
    *,
    negate: bool = False,
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
    free_thresh: float = DEFAULT_FREE_THRESH,
    alpha: NDArray[Any] | None = None,
    flavor: Flavor = "ros1",
    maxval: int = 255,
) -> NDArray[np.int8]:
    """The cell values a map_server gives pixels, by its documented rules (vectorised).

    Args:
        grey: The pixels' channel means (0..``maxval``, may be fractional for colour images).
            For ``ros1`` this is SDL's mean over the averaged channels; for ``nav2`` the mean of
            the colour channels (and, in trinary mode, the alpha channel, as Nav2 does).
        mode: ``trinary``, ``scale`` or ``raw``.
        negate: The YAML's ``negate``.
        occupied_thresh: The YAML's ``occupied_thresh``.
        free_thresh: The YAML's ``free_thresh``.
        alpha: Opacity per pixel (0..``maxval``; ``None`` = opaque). ROS 1 treats a pixel as
            unknown in scale mode when its alpha byte is 0; Nav2 when it is not fully opaque.
        flavor: ``ros1`` (map_server 1.17) or ``nav2`` (nav2_map_server).
        maxval: Full scale of ``grey`` and ``alpha`` (255, or 65535 for 16-bit images in Nav2).

    Returns:
        int8 cell values, same shape as ``grey``.

    Examples:
        >>> load_pixel_values(np.array([0, 89, 90, 205, 206, 254]), "trinary").tolist()
        [100, 100, -1, -1, 0, 0]
        >>> load_pixel_values(np.array([255, 205, 100]), "raw").tolist()
        [-1, -51, 100]
        >>> load_pixel_values(np.array([255, 205, 100]), "raw", flavor="nav2").tolist()
        [-1, -1, 100]
    """
    g = np.asarray(grey, dtype=np.float64)
    full = float(maxval)
    if flavor == "ros1":
        avg = full - g if negate else g
        if mode == "raw":
            return np.trunc(avg).astype(np.int64).astype(np.uint8).view(np.int8)
        occ = (full - avg) / full
    elif flavor == "nav2":
        shade = g / full
        if mode == "raw":
            pct = np.floor(shade * 255.0 + 0.5)  # std::round (values are >= 0)
            out = np.where((pct >= 0) & (pct <= 100), pct, -1)
            return out.astype(np.int8)
        occ = shade if negate else 1.0 - shade
    else:
        raise RasterError(f"flavor must be ros1 or nav2, got {flavor!r}")
    out = np.full(g.shape, -1, dtype=np.int8)
    occupied = occ > occupied_thresh
    free = occ < free_thresh
    out[occupied] = 100
    out[free & ~occupied] = 0
    if mode == "trinary":
        return out
    if mode != "scale":
        raise RasterError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    between = ~occupied & ~free
    if alpha is not None:
        a = np.asarray(alpha, dtype=np.float64)
        opaque = (a >= 1.0) if flavor == "ros1" else (a >= full)
        between &= opaque
        if flavor == "nav2":
            out[~opaque] = -1
    if not between.any():
        return out
    if occupied_thresh == free_thresh:
        raise RasterError("scale mode divides by occupied_thresh - free_thresh, which is 0")
    ratio = (occ[between] - free_thresh) / (occupied_thresh - free_thresh)
    val = np.trunc(1.0 + 98.0 * ratio) if flavor == "ros1" else np.rint(ratio * 100.0)
    out[between] = val.astype(np.int64).astype(np.uint8).view(np.int8)
    return out
