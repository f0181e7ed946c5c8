"""5xx: can a robot of the given radius reach every goal and dock? (rasterised check)"""

from __future__ import annotations
