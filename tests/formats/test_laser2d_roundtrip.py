"""Hypothesis round trips of .2d logs, per logger version: scans -> text -> scans."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, strategies as st
from hypothesis.extra import numpy as hnp

from mapkit.formats.laser2d import dumps_log, goal_event, loads_log, loop_event
from mapkit.model.scan import LaserConfig, LaserLog, LaserScan, LogHeader, Pose2D

CREATED = {
    1: (),
    2: ("Created by ARIA's ArSickLogger",),
    3: ("Created by ARIA's ArLaserLogger",),
    4: ("Created by ArLaserLogger",),
}
mm = st.integers(-50_000, 50_000).map(float)
deg2 = st.integers(-17_999, 18_000).map(lambda k: k / 100)  # what %.2f keeps
word = st.text(
    st.characters(whitelist_categories=("L", "N"), whitelist_characters="._-"),
    min_size=1,
    max_size=10,
)


@st.composite
def logs(draw: st.DrawFn, version: int, exact: bool = True) -> LaserLog:
    """A log whose every value survives the version's text formats (``exact``), or any values."""
    n = draw(st.integers(2, 25))
    lth = draw(deg2) if (version == 4 or not exact) else 0.0
    if version == 4:
        a = draw(st.integers(-18_000, 18_000)) / 100
        b = draw(st.integers(-18_000, 18_000).filter(lambda v: v != a * 100)) / 100
        laser = LaserConfig(
            pose=Pose2D(draw(mm), draw(mm), lth),
            start=a,
            end=b,
            count=n,
            name=draw(word),
            z=draw(mm),
        )
    elif version == 3:
        lo = draw(st.integers(-180, 179))
        hi = draw(st.integers(lo + 1, 180))
        laser = LaserConfig(
            pose=Pose2D(draw(mm), draw(mm), lth), start=hi - lth, end=lo - lth, count=n
        )
    else:
        a = draw(st.integers(-180, 179))
        laser = LaserConfig(
            pose=Pose2D(draw(mm), draw(mm), lth),
            start=a,
            end=draw(st.integers(a + 1, 180)),
            count=n,
        )
    pose = st.builds(Pose2D, mm, mm, deg2)
    v1pose = st.builds(Pose2D, mm, mm, deg2)
    readings = hnp.arrays(np.float64, (n, 2), elements=st.integers(-30_000, 30_000).map(float))
    ranges = hnp.arrays(np.float64, (n,), elements=st.integers(0, 32_767).map(float))
    records: list = []
    scan_id = 0
    for _ in range(draw(st.integers(0, 6))):
        t = draw(st.integers(0, 10**7)) / 1000 if version >= 2 else None
        if draw(st.booleans()) and version >= 1:
            robot = draw(v1pose if version == 1 else pose)
            rg = robot if version <= 2 else draw(pose)
            if draw(st.booleans()):
                records.append(
                    goal_event(draw(word), robot, time=t, robot_global=rg if version >= 3 else None)
                )
            else:
                records.append(
                    loop_event(
                        draw(st.sampled_from(["start", "stop"])),
                        str(draw(st.integers(1, 9))),
                        robot,
                        time=t,
                        robot_global=rg if version >= 3 else None,
                    )
                )
            continue
        scan_id += draw(st.integers(1, 3))
        if version >= 3:
            vel = (draw(deg2), draw(deg2), draw(deg2)) if draw(st.booleans()) else None
        elif version == 2:
            vel = (draw(mm), draw(mm), math.nan) if draw(st.booleans()) else None
        else:
            vel = None
        robot = draw(v1pose if version == 1 else pose)
        records.append(
            LaserScan(
                scan_id=scan_id,
                robot=robot,
                time=t,
                velocities=vel,
                robot_global=draw(pose) if version >= 3 else None,
                xy=None if version == 1 else draw(readings),
                ranges=draw(ranges) if version == 1 or draw(st.booleans()) else None,
                reflectors=draw(hnp.arrays(np.int64, (n,), elements=st.integers(0, 3)))
                if version >= 2 and draw(st.booleans())
                else None,
            )
        )
    header = LogHeader(
        version=version,
        lasers=(laser,),
        location_types=("robot", "robotGlobal") if version >= 3 else (),
        comments=CREATED[version],
    )
    return LaserLog(header=header, records=records, complete=draw(st.booleans()))


def _check_exact(log: LaserLog) -> None:
    text = dumps_log(log)
    back = loads_log(text)
    assert back == log
    assert dumps_log(back) == text


@given(logs(1))
def test_roundtrip_v1(log: LaserLog) -> None:
    _check_exact(log)


@given(logs(2))
def test_roundtrip_v2(log: LaserLog) -> None:
    _check_exact(log)


@given(logs(3))
def test_roundtrip_v3(log: LaserLog) -> None:
    _check_exact(log)


@given(logs(4))
def test_roundtrip_v4(log: LaserLog) -> None:
    _check_exact(log)


@given(st.sampled_from([2, 3]).flatmap(lambda v: logs(v, exact=False)))
def test_rotated_mount_v2_v3_keeps_world_points(log: LaserLog) -> None:
    """With a rotated mount v2/v3 store unrotated offsets: text is a fixed point, points move
    < 1 mm."""
    text = dumps_log(log)
    back = loads_log(text)
    assert dumps_log(back) == text
    laser, laser_back = log.header.laser(1), back.header.laser(1)
    for a, b in zip(log.scans, back.scans, strict=True):
        pa, pb = a.global_points(laser), b.global_points(laser_back)
        assert pa.shape == pb.shape
        assert np.all(np.abs(pa - pb) < 1.0)
