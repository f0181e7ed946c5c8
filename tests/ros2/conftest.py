"""Fixtures for the ROS 2 tests: the two DDS peers (built once) and a private network namespace."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import IN_CI
from tests.ros2.netns import NetNs
from tests.ros2.peers.build import PeerBuildError, build


def _missing(message: str) -> None:
    if IN_CI:
        pytest.fail(message)
    pytest.skip(message)


@pytest.fixture(scope="session")
def peers() -> dict[str, Path]:
    """``{"fastdds": reader, "cyclone": reader}``: fails under CI=true when they cannot be built."""
    try:
        return build()
    except PeerBuildError as err:
        _missing(f"DDS peers cannot be built: {err}")
        raise


@pytest.fixture(scope="session")
def netns() -> Iterator[NetNs]:
    """A network namespace with only lo (multicast on), for DDS discovery on this machine."""
    try:
        ns = NetNs().start()
    except (RuntimeError, OSError) as err:
        _missing(f"no private network namespace: {err}")
        raise
    yield ns
    ns.stop()
