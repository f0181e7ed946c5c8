"""One ARIA map server (ARIA 2.9.1's own ArNetworking code) per test module, with logins."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.arnet.peer import Peer, start_peer


@pytest.fixture(scope="module")
def real_maps(shared_dir: Path) -> list[Path]:
    """Every real ARIA sample map."""
    return sorted((shared_dir / "real").glob("*.map"))


@pytest.fixture(scope="module")
def peer(tmp_path_factory: pytest.TempPathFactory, real_maps: list[Path]) -> Iterator[Peer]:
    """run-mapserver serving every real sample, aria-office.map active, logins required."""
    p = start_peer(tmp_path_factory.mktemp("peer"), real_maps, active="aria-office.map")
    yield p
    p.stop()
