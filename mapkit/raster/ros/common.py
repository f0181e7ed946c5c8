"""What the ROS map reader and writer share: modes, flavours, default thresholds, map_saver's grey
levels."""

from __future__ import annotations

import logging
from typing import Literal

__all__ = [
    "DEFAULT_FREE_THRESH",
    "DEFAULT_OCCUPIED_THRESH",
    "MODES",
    "SAVER_FREE",
    "SAVER_OCCUPIED",
    "SAVER_UNKNOWN",
    "Flavor",
    "Mode",
    "log_",
]


Mode = Literal["trinary", "scale", "raw"]
Flavor = Literal["ros1", "nav2"]
MODES: tuple[str, ...] = ("trinary", "scale", "raw")
DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.196

log_ = logging.getLogger("mapkit.raster.ros")  # one logger for the whole package

#: map_saver's grey levels.
SAVER_FREE, SAVER_OCCUPIED, SAVER_UNKNOWN = 254, 0, 205
