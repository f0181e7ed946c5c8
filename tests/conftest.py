"""Shared fixtures: the real ARIA samples in ../shared, the bundled samples, a CLI runner."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, settings

ROOT = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("MAPKIT_SHARED", ROOT.parent / "shared"))
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")

settings.register_profile("dev", max_examples=60, deadline=None)
settings.register_profile(
    "ci", max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile("ci" if IN_CI else os.environ.get("HYPOTHESIS_PROFILE", "dev"))


def _require(path: Path, what: str) -> Path:
    if not path.exists():
        message = f"{what} not found at {path} (set MAPKIT_SHARED to the shared/ folder)"
        if IN_CI:
            pytest.fail(message)
        pytest.skip(message)
    return path


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """../shared beside the checkout: fails in CI when missing, skips elsewhere."""
    return _require(SHARED / "sample-data", "shared sample data")


def real_sample_names() -> list[str]:
    """Names of the real ARIA samples (empty when ../shared is absent; the fixture then fails in
    CI)."""
    folder = SHARED / "sample-data" / "real"
    names = sorted(p.name for p in folder.glob("*.map")) if folder.exists() else []
    if not names:
        names = ["<missing>"]
    return names


@pytest.fixture(params=real_sample_names())
def real_sample(request: pytest.FixtureRequest, shared_dir: Path) -> Path:
    """Each real ARIA sample map in ../shared/sample-data/real."""
    return _require(shared_dir / "real" / request.param, "real sample")


@pytest.fixture
def runner() -> CliRunner:
    """A click test runner."""
    return CliRunner()
