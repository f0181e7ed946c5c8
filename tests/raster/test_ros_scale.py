"""Scale-mode export with any thresholds: unknown cells stay unknown in ROS 1, squashing is said.

ROS 1's map_server checks the thresholds before the alpha channel, so a transparent pixel is
unknown only when its grey level lies between the thresholds. Checked with the independent
loader in :mod:`tests.raster.rosloader` (written from the documented rules) and Nav2's rules.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra import numpy as hnp

from mapkit.raster import OccupancyGrid
from mapkit.raster.errors import RasterError
from mapkit.raster.ros import read_ros_map, write_ros_map

from .rosloader import cells


@given(
    hnp.arrays(np.int8, (5, 6), elements=st.sampled_from([-1, -1, 0, 100, 30, 70])),
    st.floats(0.02, 0.6),
    st.floats(0.15, 0.4),
    st.booleans(),
)
@settings(max_examples=60, deadline=None)
def test_unknown_cells_stay_unknown_in_ros1_for_any_thresholds(
    tmp_path_factory: pytest.TempPathFactory,
    data: np.ndarray,
    free: float,
    gap: float,
    negate: bool,
) -> None:
    occ = min(1.0, free + gap)
    g = OccupancyGrid(data, 0.05, (0.0, 0.0))
    files = write_ros_map(
        g,
        tmp_path_factory.mktemp("s") / "s.yaml",
        mode="scale",
        negate=negate,
        occupied_thresh=occ,
        free_thresh=free,
    )
    ros1, _ = cells(files.yaml)
    unknown = g.data < 0
    assert (ros1[unknown] == -1).all()
    assert (ros1[g.data == 0] == 0).all() and (ros1[g.data == 100] == 100).all()
    assert np.array_equal(read_ros_map(files.yaml).data, ros1)
    nav2 = read_ros_map(files.yaml, flavor="nav2").data
    assert (nav2[unknown] == -1).all()


def test_thresholds_0_9_and_0_5_keep_unknown_unknown(tmp_path: Path) -> None:
    """The reported case: grey 205 reads as free in ROS 1 with these thresholds."""
    g = OccupancyGrid(np.array([[-1, 0, 50, 100]], dtype=np.int8), 0.05, (0.0, 0.0))
    files = write_ros_map(
        g, tmp_path / "s.yaml", mode="scale", occupied_thresh=0.9, free_thresh=0.5
    )
    assert cells(files.yaml)[0].tolist() == [[-1, 0, 50, 100]]


def test_squashing_thresholds_warn_or_refuse(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    close = {"occupied_thresh": 0.65, "free_thresh": 0.649}
    g = OccupancyGrid(np.array([[0, 25, 50, 75, 100]], dtype=np.int8), 0.05, (0.0, 0.0))
    with caplog.at_level(logging.WARNING, logger="mapkit.raster.ros"):
        write_ros_map(g, tmp_path / "a.yaml", mode="scale", **close)
    assert "3 of the 5 cell values in this grid read back more than 1 off" in caplog.text
    caplog.clear()
    with pytest.raises(
        RasterError,
        match="no grey level between them: ROS 1 map_server would "
        "read the 1 unknown cells as free or occupied",
    ):
        write_ros_map(
            OccupancyGrid(np.array([[-1, 0]], dtype=np.int8), 0.05, (0.0, 0.0)),
            tmp_path / "b.yaml",
            mode="scale",
            **close,
        )
    with caplog.at_level(logging.WARNING, logger="mapkit.raster.ros"):
        write_ros_map(
            OccupancyGrid(np.array([[0, 100]], dtype=np.int8), 0.05, (0.0, 0.0)),
            tmp_path / "c.yaml",
            mode="scale",
            **close,
        )  # nothing in between to squash
        every = OccupancyGrid(np.arange(-1, 101, dtype=np.int8)[None, :], 0.05, (0.0, 0.0))
        write_ros_map(every, tmp_path / "d.yaml", mode="scale")  # the defaults squash nothing
    assert caplog.text == ""
