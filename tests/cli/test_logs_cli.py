"""mapkit simulate / build / log-info through click's runner."""

from __future__ import annotations

import json

import numpy as np

import mapkit
from mapkit.cli.main import cli


def test_simulate_build_and_info(runner, tmp_path) -> None:
    log = tmp_path / "office.2d"
    res = runner.invoke(
        cli,
        [
            "simulate",
            "--sample",
            "office",
            "-o",
            str(log),
            "--loop",
            "--readings",
            "181",
            "--seed",
            "3",
        ],
    )
    assert res.exit_code == 0, res.output
    assert "wrote" in res.output and (tmp_path / "office.truth.tsv").exists()
    res = runner.invoke(cli, ["log-info", str(log), "--json"])
    assert res.exit_code == 0, res.output
    info = json.loads(res.output)
    assert info["version"] == 4 and info["scans"] > 100 and info["events"] == {"goal": 7, "loop": 2}
    assert info["lasers"][0]["readings"] == 181
    res = runner.invoke(cli, ["log-info", str(log)])
    assert "laser 1 'sim_laser_1': 181 readings from -90 to 90 deg" in res.output
    out = tmp_path / "office.map"
    res = runner.invoke(cli, ["build", str(log), "-o", str(out), "--json"])
    assert res.exit_code == 0, res.output
    summary = json.loads(res.output)
    assert summary["points"] == mapkit.load(out).scan.num_points
    assert summary["loops"]["tags_matched"] == 1
    fitted = summary["registration"]["odometry_turn_error"]
    assert fitted is not None and not summary["registration"]["odometry_turn_error_stated"]
    # The robot's turn error stated (as its owner knows it; this robot's logged turns err
    # 0.8 %): taken as stated, not fitted; stated eight times too low, the turns rule it out.
    res = runner.invoke(
        cli, ["build", str(log), "-o", str(out), "--force", "--json", "--turn-error", "0.008"]
    )
    assert res.exit_code == 0, res.output
    stated = json.loads(res.output)["registration"]
    assert stated["odometry_turn_error"] == 0.008 and stated["odometry_turn_error_stated"]
    assert not stated["odometry_turn_error_ruled_out"]
    res = runner.invoke(
        cli, ["build", str(log), "-o", str(out), "--force", "--turn-error", "0.001"]
    )
    assert res.exit_code == 0, res.output
    assert "this log's turns rule out the one stated" in res.output
    res = runner.invoke(cli, ["build", str(log), "-o", str(out), "--force", "--turn-error", "-1"])
    assert res.exit_code == 2 and "--turn-error" in res.output
    res = runner.invoke(cli, ["build", str(log), "-o", str(out)])
    assert res.exit_code == 2 and "--force" in res.output
    res = runner.invoke(
        cli, ["build", str(log), "-o", str(out), "--force", "--no-register", "--resolution", "50"]
    )
    assert res.exit_code == 0, res.output
    assert "raw odometry" in res.output and mapkit.load(out).scan.resolution == 50


def test_simulate_options_and_versions(runner, tmp_path) -> None:
    room = tmp_path / "room.map"
    room.write_text("2D-Map\nLINES\n0 0 6000 0\n6000 0 6000 4000\n6000 4000 0 4000\n0 4000 0 0\n")
    log = tmp_path / "room.2d"
    res = runner.invoke(
        cli,
        [
            "simulate",
            str(room),
            "-o",
            str(log),
            "--version",
            "2",
            "--waypoints",
            "1000,1000 5000,3000",
            "--no-truth",
            "--fov",
            "240",
        ],
    )
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "room.truth.tsv").exists()
    assert "version: 2" in log.read_text().splitlines()[:4]
    res = runner.invoke(
        cli, ["simulate", str(room), "-o", str(log), "--force", "--waypoints", "1000,1000,5"]
    )
    assert res.exit_code == 2 and "--waypoints: expected 2 numbers" in res.output
    res = runner.invoke(cli, ["simulate", "-o", str(log)])
    assert res.exit_code == 2 and "MAP_FILE or --sample" in res.output


def test_bad_log_is_one_line_error(runner, tmp_path) -> None:
    bad = tmp_path / "bad.2d"
    bad.write_text(
        "LaserOdometryLog\nversion: 4\nsick1conf: -90 90 2\n"
        "scanId: 0\nrobot: 0 0 0\nscan1: 1 2 3 \n"
    )
    res = runner.invoke(cli, ["build", str(bad), "-o", str(tmp_path / "x.map")])
    assert res.exit_code == 1
    assert "bad.2d:6: scan1: odd number of values (3)" in res.output
    assert "Traceback" not in res.output
    res = runner.invoke(cli, ["log-info", str(bad), "--tolerant"])
    assert res.exit_code == 0 and "MK704" in res.output
    res = runner.invoke(cli, ["log-info", str(bad)])
    assert res.exit_code == 1 and "bad.2d:6:" in res.output


ROOM = "2D-Map\nLINES\n0 0 8000 0\n8000 0 8000 5000\n8000 5000 0 5000\n0 5000 0 0\n"


def _room_log(runner, tmp_path, *extra: str):
    room = tmp_path / "world.map"
    room.write_text(ROOM)
    log = tmp_path / "room.2d"
    res = runner.invoke(
        cli,
        [
            "simulate",
            str(room),
            "-o",
            str(log),
            "--waypoints",
            "6500,1500 6500,3500",
            "--start",
            "1500,2500,0",
            "--loop",
            "--laps",
            "3",
            "--seed",
            "4",
            "--readings",
            "181",
            *extra,
        ],
    )
    assert res.exit_code == 0, res.output
    return log


def test_repeated_tags_merge_into_one_goal(runner, tmp_path) -> None:
    log = _room_log(
        runner,
        tmp_path,
        "--scale-error",
        "0.01",
        "--turn-slip",
        "0.03",
        "--outliers",
        "0.02",
        "--people",
        "1",
    )
    out = tmp_path / "built.map"
    res = runner.invoke(cli, ["build", str(log), "-o", str(out), "--no-lines"])
    assert res.exit_code == 0, res.output
    goals = [o for o in mapkit.load(out).objects if o.type == "GoalWithHeading"]
    # Three laps past goal1 and goal2: one object each, at the mean of the laps' poses.
    assert sorted(g.name for g in goals) == ["goal1", "goal2"]
    g1 = next(g for g in goals if g.name == "goal1")
    assert abs(g1.x - 6500) < 100 and abs(g1.y - 1500) < 100
    res = runner.invoke(
        cli, ["build", str(log), "-o", str(out), "--force", "--no-lines", "--keep-all-tags"]
    )
    assert res.exit_code == 0, res.output
    goals = [o for o in mapkit.load(out).objects if o.type == "GoalWithHeading"]
    assert sorted(g.name for g in goals) == ["goal1"] * 3 + ["goal2"] * 3


def test_poses_and_report(runner, tmp_path) -> None:
    from mapkit.build import build_map
    from mapkit.build.report import read_poses

    log = _room_log(runner, tmp_path)
    out, poses, png = tmp_path / "built.map", tmp_path / "room.tsv", tmp_path / "report.png"
    res = runner.invoke(
        cli, ["build", str(log), "-o", str(out), "--poses", str(poses), "--report", str(png)]
    )
    assert res.exit_code == 0, res.output
    assert f"wrote {poses}:" in res.output and f"wrote {png} (PNG)" in res.output
    assert "loops closed" in res.output and "moved from odometry" in res.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    ids, p, o = read_poses(poses)
    result = build_map(log, lines=False)
    assert np.array_equal(ids, result.scan_ids)
    assert np.allclose(p, result.poses, atol=0.06) and np.allclose(o, result.odometry, atol=0.06)
    # Existing outputs are refused before any work, unless --force.
    res = runner.invoke(
        cli, ["build", str(log), "-o", str(tmp_path / "new.map"), "--poses", str(poses)]
    )
    assert res.exit_code == 2 and "--force" in res.output
    res = runner.invoke(
        cli,
        [
            "build",
            str(log),
            "-o",
            str(tmp_path / "new.map"),
            "--json",
            "--report",
            str(tmp_path / "r2.png"),
        ],
    )
    assert res.exit_code == 0, res.output
    figs = json.loads(res.output)["report_figures"]
    assert figs["scans"] == len(ids) and figs["residual_mm"]["median"] > 0


def test_read_poses_names_the_bad_line(tmp_path) -> None:
    import pytest

    from mapkit.build.report import read_poses
    from mapkit.errors import MapkitError

    bad = tmp_path / "p.tsv"
    bad.write_text("scanId\tx\ty\tth\todo_x\todo_y\todo_th\n0 1 2 3 4 5 6\n1 1 2 x 4 5 6\n")
    with pytest.raises(MapkitError, match=r"p\.tsv:3: expected"):
        read_poses(bad)


def test_a_lagging_laser_is_simulated_and_its_lag_measured(runner, tmp_path) -> None:
    log = _room_log(
        runner, tmp_path, "--scan-lag", "-0.04", "--trans-error", "0.001", "--rot-error", "0.001"
    )
    out = tmp_path / "built.map"
    res = runner.invoke(cli, ["build", str(log), "-o", str(out), "--no-lines", "--json"])
    assert res.exit_code == 0, res.output
    reg = json.loads(res.output)["registration"]
    assert abs(reg["scan_lag_ms"] + 40.0) < 4.0, reg
    res = runner.invoke(cli, ["build", str(log), "-o", str(out), "--no-lines", "--force"])
    assert res.exit_code == 0, res.output
    assert "ms newer than the poses logged with them" in res.output


def test_a_lag_that_varies_is_simulated_and_its_spread_reported(runner, tmp_path) -> None:
    args = ("--scan-lag", "0.04", "--trans-error", "0.001", "--rot-error", "0.001")
    steady = _room_log(runner, tmp_path, *args)
    out = tmp_path / "built.map"
    res = runner.invoke(cli, ["build", str(steady), "-o", str(out), "--no-lines", "--json"])
    assert res.exit_code == 0, res.output
    reg = json.loads(res.output)["registration"]
    assert reg["scan_lag_jitter_ms"] == 0.0, reg  # one lag for every sweep
    varying = tmp_path / "varying.2d"
    steady.rename(varying)
    log = _room_log(runner, tmp_path, *args, "--scan-lag-jitter", "0.06")
    res = runner.invoke(cli, ["build", str(log), "-o", str(out), "--no-lines", "--force"])
    assert res.exit_code == 0, res.output
    assert "ms from sweep to sweep" in res.output, res.output


def test_a_second_lasers_sweeps_are_merged_into_their_cycles_scan(runner, tmp_path) -> None:
    """`simulate --second-laser` logs a rear laser beside the front one, as ARIA's logger does
    (a sweep of each per ``logTime:``); `build` matches each cycle's two sweeps as one scan and
    says so. A second laser needs a version 4 log."""
    from mapkit.formats.laser2d import read_log

    path = _room_log(runner, tmp_path, "--second-laser", "-200,0,180")
    log = read_log(path)
    assert [las.number for las in log.header.lasers] == [1, 2]
    assert log.header.lasers[1].pose == (-200.0, 0.0, 180.0)
    text = path.read_text()
    assert text.count("logTime:") == text.count("scan2:") == text.count("scan1:")
    n = len(log.scans) // 2
    out = tmp_path / "built.map"
    res = runner.invoke(cli, ["build", str(path), "-o", str(out), "--no-lines"])
    assert res.exit_code == 0, res.output
    assert f"scans: {n} used of {2 * n}" in res.output, res.output
    assert f"({n} sweeps of further lasers merged into their cycle's scan)" in res.output
    room = tmp_path / "world.map"
    res = runner.invoke(
        cli,
        [
            "simulate",
            str(room),
            "-o",
            str(tmp_path / "v3.2d"),
            "--version",
            "3",
            "--second-laser",
            "-200,0,180",
        ],
    )
    assert res.exit_code != 0 and "version 4" in res.output, res.output


def test_a_robots_turn_error_learnt_from_several_logs(runner, tmp_path) -> None:
    """mapkit turn-error registers each log and fits their turns at once: what the API's
    robot_turn_error gives for the same logs, printed with each log's own fit and the build
    command to use it with; a robot that slips 2 % in its turns is told from one that errs
    0.1 %."""
    from mapkit.build import build_map, robot_turn_error

    def logs(rot_error: str) -> list[str]:
        paths = []
        for seed in ("1", "2"):
            path = tmp_path / f"office-{rot_error}-{seed}.2d"
            res = runner.invoke(
                cli,
                [
                    *("simulate", "--sample", "office", "-o", str(path), "--seed", seed),
                    *("--rot-error", rot_error, "--drift", "0", "--readings", "181"),
                ],
            )
            assert res.exit_code == 0, res.output
            paths.append(str(path))
        return paths

    good, slipping = logs("0.001"), logs("0.02")
    res = runner.invoke(cli, ["turn-error", *good, "--json"])
    assert res.exit_code == 0, res.output
    found = json.loads(res.output)
    builds = [build_map(p, lines=False) for p in good]
    assert found["turn_error"] == round(robot_turn_error(builds), 5)
    assert [e["turning_steps"] for e in found["logs"]] == [
        len(b.turns.disagreement) for b in builds
    ]
    assert found["turning_steps"] == sum(e["turning_steps"] for e in found["logs"]) > 20
    assert found["turn_error"] < 0.004
    res = runner.invoke(cli, ["turn-error", *slipping])
    assert res.exit_code == 0, res.output
    lines = [line for line in res.output.splitlines() if not line.startswith("registering")]
    assert lines[0].startswith(f"{slipping[0]}: ") and "this log alone:" in lines[0]
    assert lines[2].startswith("the robot's turns err ") and "in 2 logs" in lines[2]
    assert lines[3].startswith("  few turning steps:")  # two logs' are few
    stated = float(lines[4].rsplit("--turn-error ", 1)[1])
    assert stated > 3 * found["turn_error"], (stated, found["turn_error"])
    # A log without turns: nothing to learn from, said so.
    room, straight = tmp_path / "world.map", tmp_path / "straight.2d"
    room.write_text(ROOM)
    res = runner.invoke(
        cli,
        [
            *("simulate", str(room), "-o", str(straight), "--waypoints", "6500,2500"),
            *("--start", "1500,2500,0", "--readings", "181"),
        ],
    )
    assert res.exit_code == 0, res.output
    res = runner.invoke(cli, ["turn-error", str(straight)])
    assert res.exit_code == 1 and "too few to learn the turns' error from" in res.output
    assert f"{straight}: 0 turning steps; this log alone: too few turns to fit" in res.output
