"""The trajectory file round trip and the report figures of mapkit build."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from mapkit.build import BuildResult
from mapkit.build.report import read_poses, report_figures, write_poses
from mapkit.model import MapData

coords = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
angles = st.floats(-180, 180, allow_nan=False, allow_infinity=False)


@st.composite
def results(draw) -> BuildResult:
    n = draw(st.integers(1, 30))
    poses = np.column_stack(
        [
            draw(arrays(np.float64, n, elements=coords)),
            draw(arrays(np.float64, n, elements=coords)),
            draw(arrays(np.float64, n, elements=angles)),
        ]
    )
    odo = poses + draw(arrays(np.float64, (n, 3), elements=st.floats(-1e3, 1e3)))
    ids = np.array(sorted(draw(st.sets(st.integers(0, 10**9), min_size=n, max_size=n))))
    res = draw(arrays(np.float64, n, elements=st.one_of(st.just(np.nan), st.floats(0, 100))))
    return BuildResult(
        map=MapData(),
        poses=poses,
        odometry=odo,
        scan_ids=ids,
        residuals=res,
        closures=np.array([[0, n - 1]]),
    )


@settings(max_examples=40, deadline=None)
@given(results())
def test_poses_round_trip(tmp_path_factory, result: BuildResult) -> None:
    path = tmp_path_factory.mktemp("p") / "poses.tsv"
    write_poses(result, path)
    ids, poses, odo = read_poses(path)
    assert np.array_equal(ids, result.scan_ids)
    assert np.allclose(poses[:, :2], result.poses[:, :2], atol=0.05)
    assert np.allclose(poses[:, 2], result.poses[:, 2], atol=0.0005)
    assert np.allclose(odo[:, :2], result.odometry[:, :2], atol=0.05)
    figs = report_figures(result)
    assert figs["scans"] == len(ids) and figs["loops_closed"] == 1
    assert figs["matched"] == int(np.isfinite(result.residuals).sum())
    assert figs["moved_from_odometry_mm"]["max"] >= figs["moved_from_odometry_mm"]["median"]
