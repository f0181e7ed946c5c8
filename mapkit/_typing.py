"""Type aliases shared across mapkit."""

from __future__ import annotations

import os
from typing import Union

import numpy as np
from numpy.typing import NDArray

PathLike = Union[str, "os.PathLike[str]"]
#: Integer millimetre points, shape (N, 2), dtype int64.
PointArray = NDArray[np.int64]
#: Integer millimetre segments x1 y1 x2 y2, shape (M, 4), dtype int64.
LineArray = NDArray[np.int64]
