"""Fixtures for the edit tests: each real sample loaded once."""

from __future__ import annotations

from pathlib import Path

import pytest

from mapkit.formats.map import dumpb, load
from mapkit.model import MapData

_LOADED: dict[Path, MapData] = {}


@pytest.fixture
def sample(real_sample: Path) -> MapData:
    """The real sample as a map (loaded once per session; maps are immutable)."""
    if real_sample not in _LOADED:
        _LOADED[real_sample] = load(real_sample)
    return _LOADED[real_sample]


@pytest.fixture
def canonical(sample: MapData) -> bytes:
    """The sample's canonical bytes (what ARIA writes for it)."""
    return dumpb(sample)
