"""Shared helpers of the editing-command tests: invoke mapkit, copy real samples to tmp_path."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from mapkit.cli.main import cli
from mapkit.formats.map import load, save

COLUMBIA = "aria294-columbia.map"
OMRON = "omron-ld-showroom-ex4.map"


def run(runner: CliRunner, *args: object) -> Result:
    """``mapkit ARGS...`` (any argument turned into text)."""
    return runner.invoke(cli, [str(a) for a in args], catch_exceptions=False)


def copy_sample(shared_dir: Path, tmp_path: Path, name: str) -> Path:
    """A writable copy of a real sample."""
    dst = tmp_path / name
    shutil.copyfile(shared_dir / "real" / name, dst)
    return dst


def light_sample(shared_dir: Path, tmp_path: Path, name: str) -> Path:
    """A real sample with its header, info, objects and lines but no points (quick to load)."""
    m = load(shared_dir / "real" / name)
    dst = tmp_path / name
    save(m.with_scan(m.scan.with_data(points=m.points[:0])), dst)
    return dst


@pytest.fixture
def copy(real_sample: Path, tmp_path: Path) -> Path:
    """A writable copy of each real sample."""
    return copy_sample(real_sample.parent.parent, tmp_path, real_sample.name)
