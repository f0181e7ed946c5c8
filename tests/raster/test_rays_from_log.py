"""Free space ray-cast from a real ``.2d`` log (``rasterize(log=...)``,
``mapkit rasterize --log``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import mapkit
from mapkit.cli.main import cli
from mapkit.raster.grid import FREE, OCCUPIED, UNKNOWN
from mapkit.raster.rasterize import RasterError, rasterize, rays_from_log
from mapkit.samples import sample_path
from mapkit.simulate import simulate_log


@pytest.fixture(scope="module")
def office_log(tmp_path_factory: pytest.TempPathFactory) -> tuple[mapkit.MapData, Path]:
    m = mapkit.load(sample_path("office"))
    sim = simulate_log(
        m,
        waypoints=[(4000, 6000), (12000, 6000)],
        start=(1500, 6000, 0),
        translation_error=0,
        rotation_error=0,
        drift=0,
        range_noise=0,
        seed=3,
    )
    path = tmp_path_factory.mktemp("log") / "office.2d"
    sim.save(path)
    return m, path


def test_rays_start_at_the_laser_and_end_on_walls(office_log: tuple[mapkit.MapData, Path]) -> None:
    m, path = office_log
    rays = rays_from_log(path)
    assert rays.shape[1] == 4 and len(rays) > 1000
    # every beam starts inside the corridor the robot drove along (y 5000..7000)
    assert np.all((rays[:, 1] > 5000) & (rays[:, 1] < 7000))
    walls = rasterize(m, free="none")
    ends = walls.values_at(rays[:, 2:])
    assert np.mean(ends == OCCUPIED) > 0.9  # hits land on wall cells (a few graze corners)


def test_free_space_is_what_the_beams_saw(office_log: tuple[mapkit.MapData, Path]) -> None:
    m, path = office_log
    grid = rasterize(m, log=path)
    flood = rasterize(m)
    free = grid.data == FREE
    assert free.sum() > 1000
    assert not np.any(free & (flood.data == OCCUPIED))
    # the corridor the robot drove along is free; the far offices it never saw into are not
    assert grid.values_at(np.array([[8000, 6000]]))[0] == FREE
    unseen = np.array([[19500, 11500]])  # a corner of office 4 no beam through its door reaches
    assert grid.values_at(unseen)[0] == UNKNOWN and flood.values_at(unseen)[0] == FREE
    assert (flood.data == FREE).sum() > free.sum()


def test_log_and_rays_together_are_refused(office_log: tuple[mapkit.MapData, Path]) -> None:
    m, path = office_log
    with pytest.raises(RasterError, match="not both"):
        rasterize(m, log=path, rays_mm=np.zeros((1, 4)))


def test_cli_rasterize_with_log(office_log: tuple[mapkit.MapData, Path], tmp_path: Path) -> None:
    _m, log = office_log
    out = tmp_path / "office.yaml"
    result = CliRunner().invoke(
        cli, ["rasterize", str(sample_path("office")), "-o", str(out), "--log", str(log)]
    )
    assert result.exit_code == 0, result.output
    assert out.exists() and (tmp_path / "office.pgm").exists()
