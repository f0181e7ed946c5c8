"""The .2d reader and writer: FORMATS.md part B rules, events, bad input, streaming."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from mapkit.diagnostics import IssueCode
from mapkit.errors import LogFormatError
from mapkit.formats.laser2d import (
    dumps_log,
    goal_event,
    goal_fields,
    iter_log,
    loads_log,
    log_summary,
    loop_event,
    read_log,
    recover_log,
    write_log,
)
from mapkit.model.scan import LaserConfig, LaserLog, LaserScan, LogHeader, Pose2D

V4_HEAD = (
    "LaserOdometryLog\n#Created by ArLaserLogger\nversion: 4\n"
    "sick1pose: {lx} {ly} {lth}\nsick1conf: -90.00 90.00 {n}\nsick1name: lms\n"
    "scan1pose: {lx} {ly} 0 {lth}\nscan1conf: -90.00 90.00 {n}\nscan1name: lms\n"
    "locationTypes: robot robotGlobal\n"
)


def v4(body: str, *, lx: int = 0, ly: int = 0, lth: str = "0.00", n: int = 2) -> bytes:
    return (V4_HEAD.format(lx=lx, ly=ly, lth=lth, n=n) + body).encode()


def test_t25_v4_reading_to_global_point() -> None:
    """FORMATS.md T25: one valid point, robot frame (100, 500), global (500, 100)."""
    log = read_log(
        v4(
            "logTime: 1.000\nvelocities: 0.00 0.00 0.00\nscanId: 0\n"
            "robot: 1000 0 90.00\nrobotGlobal: 1000 0 90.00\nscan1: 500 0  0 0 \n"
            "# End of log\n",
            lx=100,
            lth="90.00",
        )
    )
    (scan,) = log.scans
    laser = log.header.laser(1)
    assert scan.valid.tolist() == [True, False]
    assert np.allclose(scan.robot_points(laser), [[100, 500]])
    assert np.allclose(scan.global_points(laser), [[500, 100]])
    assert log.complete


@pytest.mark.parametrize("version", [2, 3])
def test_v2_v3_pairs_are_robot_frame_offsets(version: int) -> None:
    """B.5: in v2/v3 a pair is the hit in the robot frame minus the mount offset (not rotated)."""
    head = f"LaserOdometryLog\nversion: {version}\nsick1pose: 100 0 90.00\nsick1conf: -90 90 2\n"
    body = (
        "scan1Id: 1\ntime: 5.7\n"
        + (
            "robot: 1000 0 90.00 0 0\n"
            if version == 2
            else "velocities: 0.00 0.00 0.00\nrobot: 1000 0 90.00\nrobotGlobal: 1000 0 90.00\n"
        )
        + "scan1: 500 0  0 0 \n"
    )
    log = loads_log(head + body)
    (scan,) = log.scans
    laser = log.header.laser(1)
    assert np.allclose(scan.robot_points(laser), [[600, 0]])
    assert np.allclose(scan.global_points(laser), [[1000, 600]])
    # time: 5.7 is 5 s and 7 ms (the unpadded milliseconds bug)
    assert scan.time == pytest.approx(5.007)


def test_v3_raw_ranges_run_from_the_largest_angle() -> None:
    """B.5: v3 writes sick1: from the largest angle down while sick1conf lists min then max."""
    log = loads_log(
        "LaserOdometryLog\nversion: 3\nsick1pose: 0 0 0.00\nsick1conf: -90 90 3\n"
        "locationTypes: robot robotGlobal\nscan1Id: 1\ntime: 0.0\n"
        "robot: 0 0 0.00\nrobotGlobal: 0 0 0.00\nsick1: 1000 2000 3000\n"
        "scan1: 0 1000  2000 0  0 -3000 \n"
    )
    scan = log.scans[0]
    laser = log.header.laser(1)
    assert laser.angles().tolist() == [90.0, 0.0, -90.0]
    from_ranges = LaserScan(scan_id=1, ranges=scan.ranges).laser_points(laser)
    assert np.allclose(from_ranges, scan.laser_points(laser), atol=1e-9)
    assert "sick1: 1000 2000 3000" in dumps_log(log)


def test_v1_raw_ranges_and_scan_comment() -> None:
    text = (
        "LaserOdometryLog\nversion: 1\nsick1pose: 0 0 0\nsick1conf: -90 90 3\n"
        "#scan1\nrobot: 10.5 20.25 45.0\nrobot_id: 0\nsick1: 1000 0 2000\n"
        "#scan2\nrobot: 11 20 45\nrobot_id: 0\nsick1: 1000 1000 1000\n"
    )
    log = loads_log(text)
    assert [s.scan_id for s in log.scans] == [1, 2]
    s = log.scans[0]
    assert s.robot == Pose2D(10.5, 20.25, 45.0)
    assert s.time is None and s.xy is None
    assert np.allclose(s.laser_points(log.header.laser(1)), [[0, -1000], [0, 2000]], atol=1e-9)
    assert loads_log(dumps_log(log)) == log


def test_events_goals_loops_tags_and_unknown_lines_survive() -> None:
    body = (
        "logTime: 0.100\nvelocities: 0.00 0.00 0.00\nscanId: 0\nrobot: 0 0 0.00\n"
        "robotGlobal: 0 0 0.00\nscan1: 1000 0  0 0 \n"
        "time: 0.200\nrobot: 5 6 7.00\nrobotGlobal: 5 6 7.00\n"
        'cairn: GoalWithHeading "" ICON_GOALWITHHEADING "goal1"\n'
        "time: 0.300\nrobot: 5 6 7.00\nrobotGlobal: 5 6 7.00\nloop: start 1\n"
        "time: 0.400\nrobot: 5 6 7.00\nrobotGlobal: 5 6 7.00\nloop stop 1\n"
        "time: 0.500\nrobot: 5 6 7.00\nrobotGlobal: 5 6 7.00\nmy custom tag\n"
        "serverInfo: hello world\n"
        "logTime: 0.600\nvelocities: 0.00 0.00 0.00\nscanId: 1\nrobot: 0 0 0.00\n"
        "robotGlobal: 0 0 0.00\nintensity1: 5 5\nscan1: 1000 0  0 0 \n# End of log\n"
    )
    log, issues = recover_log(v4(body))
    kinds = [(e.kind, e.name, e.action) for e in log.events]
    assert kinds == [
        ("goal", "goal1", ""),
        ("loop", "1", "start"),
        ("loop", "1", "stop"),
        ("tag", "", ""),
        ("info", "", ""),
    ]
    goal = log.events[0]
    assert goal.robot == Pose2D(5, 6, 7) and goal.time == pytest.approx(0.2)
    assert goal_fields(goal) == ("GoalWithHeading", "", "ICON_GOALWITHHEADING", "goal1")
    assert log.scans[1].extra == ("intensity1: 5 5",)
    assert {int(i.code) for i in issues} == {int(IssueCode.LOG_UNKNOWN_TAG)}
    text = dumps_log(log)
    assert "my custom tag\n" in text and "serverInfo: hello world\n" in text
    assert "intensity1: 5 5\nscan1:" in text
    assert loads_log(text) == log


def test_goal_and_loop_event_helpers() -> None:
    assert (
        goal_event("desk", Pose2D(1, 2, 3)).text
        == 'cairn: GoalWithHeading "" ICON_GOALWITHHEADING "desk"'
    )
    assert loop_event("stop", "2", Pose2D(0, 0, 0)).text == "loop: stop 2"
    with pytest.raises(ValueError, match="start, stop or end"):
        loop_event("halt", "1", Pose2D(0, 0, 0))


# -- bad input ---------------------------------------------------------------------------------

GOOD = (
    "logTime: 0.100\nvelocities: 0.00 0.00 0.00\nscanId: 0\nrobot: 0 0 0.00\n"
    "robotGlobal: 0 0 0.00\nscan1: 1000 0  0 0 \n"
)
HEAD_LINES = V4_HEAD.count("\n")


@pytest.mark.parametrize(
    ("bad", "line", "code", "message"),
    [
        (
            "scanId: 1\nrobot: 0 0 0.00\nscan1: 1000 0  0 0  5 5 \n",
            3,
            IssueCode.LOG_WRONG_READING_COUNT,
            r"has 3 readings, sick1conf: says 2",
        ),
        (
            "scanId: 1\nrobot: 0 0 0.00\nscan1: 1000 0  0 \n",
            3,
            IssueCode.LOG_WRONG_READING_COUNT,
            r"odd number of values",
        ),
        (
            "scanId: 1\nrobot: 0 0 0.00\nscan1: 1000 nan  0 0 \n",
            3,
            IssueCode.LOG_NON_FINITE,
            r"NaN or infinite",
        ),
        (
            "scanId: 1\nrobot: nan 0 0.00\nscan1: 1000 0  0 0 \n",
            2,
            IssueCode.LOG_NON_FINITE,
            r"robot: NaN",
        ),
        (
            "scanId: 1\nrobot: 0 zero 0.00\nscan1: 1000 0  0 0 \n",
            2,
            IssueCode.LOG_BAD_VALUE,
            r"robot: values that are not numbers",
        ),
        # Numbers are read as C's strtod reads them: Python's '1_0' and a cut-off hex are not.
        (
            "scanId: 1\nrobot: 0 0 0.00\nscan1: 1000 1_0  0 0 \n",
            3,
            IssueCode.LOG_BAD_VALUE,
            r"scan1: values that are not numbers",
        ),
        (
            "scanId: 1\nrobot: 0 0 0.00\nscan1: 1000 0x1g  0 0 \n",
            3,
            IssueCode.LOG_BAD_VALUE,
            r"scan1: values that are not numbers",
        ),
        (
            "scanId: 1\nrobot: 0 0 1_0\nscan1: 1000 0  0 0 \n",
            2,
            IssueCode.LOG_BAD_VALUE,
            r"robot: values that are not numbers",
        ),
        (
            "scanId: 1\nrobot: 0 0 0.00\nscan1: 1000 1e999  0 0 \n",
            3,
            IssueCode.LOG_NON_FINITE,
            r"NaN or infinite",
        ),
        (
            "logTime: 1_0\nscanId: 1\nrobot: 0 0 0.00\nscan1: 1000 0  0 0 \n",
            1,
            IssueCode.LOG_BAD_VALUE,
            r"logTime: expects seconds.milliseconds",
        ),
        (
            "scanId: 1_0\nrobot: 0 0 0.00\nscan1: 1000 0  0 0 \n",
            1,
            IssueCode.LOG_BAD_VALUE,
            r"scanId: expects an integer",
        ),
        (
            "\x00\x01garbage line\nscanId: 1\nrobot: 0 0 0.00\nscan1: 1000 0  0 0 \n",
            1,
            IssueCode.LOG_GARBAGE_LINE,
            r"expected a tag",
        ),
        (
            "scanId: 1\nrobot: 0 0 0.00\nscanId: 2\nrobot: 0 0 0.00\nscan1: 1000 0  0 0 \n",
            1,
            IssueCode.LOG_INCOMPLETE_RECORD,
            r"has no scanK: line",
        ),
    ],
)
def test_bad_records_strict_and_tolerant(
    bad: str, line: int, code: IssueCode, message: str
) -> None:
    data = v4(GOOD + bad + GOOD.replace("scanId: 0", "scanId: 9") + "# End of log\n")
    first_bad = HEAD_LINES + GOOD.count("\n") + line
    with pytest.raises(LogFormatError, match=rf"^bad\.2d:{first_bad}: .*{message}"):
        read_log(data, name="bad.2d")
    log, issues = recover_log(data, name="bad.2d")
    assert log.scans[0].scan_id == 0 and log.scans[-1].scan_id == 9
    assert any(i.code == code and i.location.line == first_bad for i in issues), issues


def test_truncated_log() -> None:
    cut = v4(GOOD + GOOD.replace("scanId: 0", "scanId: 1"))[:-9]  # inside the last scan1: line
    with pytest.raises(LogFormatError, match=r"ends inside this line \(truncated\?\)"):
        read_log(cut, name="cut.2d")
    log, issues = recover_log(cut)
    assert len(log.scans) == 1
    codes = [i.code for i in issues]
    assert IssueCode.LOG_TRUNCATED in codes and IssueCode.LOG_NO_END_MARK in codes
    mid = v4(GOOD + "scanId: 1\nrobot: 0 0 0.00\n")
    with pytest.raises(LogFormatError, match=r"the log ends inside the record started on line"):
        read_log(mid)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"", r"empty file"),
        (b"2D-Map\nDATA\n", r"not a \.2d laser log: expected 'LaserOdometryLog'"),
    ],
)
def test_not_a_log(data: bytes, message: str) -> None:
    with pytest.raises(LogFormatError, match=message):
        read_log(data)
    with pytest.raises(LogFormatError, match=message):
        recover_log(data)


def test_bad_header_line() -> None:
    data = b"LaserOdometryLog\nversion: 4\nsick1conf: -90 ninety 2\n" + GOOD.encode()
    with pytest.raises(LogFormatError, match=r"<bytes>:3: sick1conf: .*number"):
        read_log(data)
    log, issues = recover_log(data)
    assert issues[0].code == IssueCode.LOG_BAD_HEADER_LINE and len(log.scans) == 1


def test_unknown_version_and_laser_are_noted() -> None:
    log, issues = recover_log(
        b"LaserOdometryLog\nversion: 9\nscanId: 0\nrobot: 0 0 0\nscan2: 5 5 \n"
    )
    codes = {i.code for i in issues}
    assert log.header.version == 4 and len(log.scans) == 1
    assert {IssueCode.LOG_UNKNOWN_VERSION, IssueCode.LOG_UNKNOWN_LASER} <= codes


# -- streaming and writing ---------------------------------------------------------------------


def _big_log(n: int, readings: int = 181) -> LaserLog:
    rng = np.random.default_rng(5)
    laser = LaserConfig(count=readings, start=-90, end=90, name="l")
    recs = []
    for i in range(n):
        xy = np.rint(rng.uniform(-8000, 8000, (readings, 2)))
        recs.append(
            LaserScan(
                scan_id=i,
                robot=Pose2D(i, 0, 0),
                robot_global=Pose2D(i, 0, 0),
                time=i / 10,
                velocities=(1.0, 0.0, 0.0),
                xy=xy,
            )
        )
    return LaserLog(
        header=LogHeader(lasers=(laser,), location_types=("robot", "robotGlobal")), records=recs
    )


def test_iter_log_streams_in_bounded_memory(tmp_path) -> None:
    path = tmp_path / "big.2d"
    write_log(_big_log(3000), path)
    size = path.stat().st_size
    assert size > 5_000_000
    tracemalloc.start()
    reader = iter_log(path)
    count = 0
    for _rec in reader:
        count += 1
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert count == 3000
    assert peak < size / 5, f"peak {peak} bytes for a {size}-byte log"
    assert reader.bytes_read == size


@pytest.mark.parametrize("version", [1, 2, 3, 4])
def test_versions_convert_without_moving_points(tmp_path, version: int) -> None:
    """A log written in any version reads back to the same world points (within rounding)."""
    laser = LaserConfig(pose=Pose2D(160, 20, 5.0), start=-90, end=90, count=5)
    ranges = np.array([1000.0, 0.0, 2500.0, 800.0, 3000.0])
    a = np.radians(laser.angles())
    xy = np.stack([ranges * np.cos(a), ranges * np.sin(a)], axis=1)
    scan = LaserScan(
        scan_id=1,
        robot=Pose2D(100, 200, 30),
        robot_global=Pose2D(100, 200, 30),
        time=1.5,
        ranges=ranges if version == 1 else None,
        xy=None if version == 1 else xy,
    )
    log = LaserLog(header=LogHeader(lasers=(laser,)), records=[scan])
    want = scan.global_points(laser)
    for target in (1, 2, 3, 4):
        p = tmp_path / f"v{version}-{target}.2d"
        write_log(log, p, version=target)
        back = read_log(p)
        assert back.header.version == target
        got = back.scans[0].global_points(back.header.laser(1))
        assert got.shape == want.shape
        assert np.abs(got - want).max() < 2.0, (version, target)


def test_write_log_is_atomic_and_rejects_nan(tmp_path) -> None:
    path = tmp_path / "a.2d"
    path.write_text("old")
    bad = LaserLog(records=[LaserScan(scan_id=0, xy=[[np.nan, 1.0]])])
    with pytest.raises(ValueError, match="NaN"):
        write_log(bad, path)
    assert path.read_text() == "old"
    with pytest.raises(ValueError, match="versions 1 to 4"):
        dumps_log(bad, version=5)


def test_log_summary_counts(tmp_path) -> None:
    path = tmp_path / "s.2d"
    write_log(_big_log(20, readings=11), path)
    s = log_summary(path)
    assert s["scans"] == 20 and s["readings"] == 220 and s["version"] == 4
    assert s["path_length_m"] == pytest.approx(0.019)
    assert s["time_span_s"] == pytest.approx(1.9)
    assert s["complete"] and s["issues"] == []


@pytest.mark.parametrize(
    ("name", "version", "readings", "loops"),
    [("office-loop", 4, 361, 2), ("building-labs", 3, 181, 0)],
)
def test_bundled_logs(name: str, version: int, readings: int, loops: int) -> None:
    from mapkit.samples import sample_path
    from mapkit.simulate import read_truth, truth_path_for

    path = sample_path(name)
    assert path.suffix == ".2d" and path.stat().st_size < 2_000_000
    log, issues = recover_log(path)
    assert issues == [] and log.complete
    assert log.header.version == version and log.header.laser(1).count == readings
    assert sum(e.kind == "loop" for e in log.events) == loops
    ids, truth = read_truth(truth_path_for(path))
    assert ids.tolist() == [s.scan_id for s in log.scans]
    drift = np.hypot(*(log.poses()[:, :2] - truth[:, :2]).T)
    assert drift[0] < 1.0 and drift.max() > 100.0  # odometry drifts away from the truth
