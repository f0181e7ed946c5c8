"""mapkit simulate / build / log-info through click's runner."""

from __future__ import annotations

import json

import mapkit
from mapkit.cli.main import cli


def test_simulate_build_and_info(runner, tmp_path) -> None:
    log = tmp_path / "office.2d"
    res = runner.invoke(cli, ["simulate", "--sample", "office", "-o", str(log), "--loop",
                              "--readings", "181", "--seed", "3"])
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
    res = runner.invoke(cli, ["build", str(log), "-o", str(out)])
    assert res.exit_code == 2 and "--force" in res.output
    res = runner.invoke(cli, ["build", str(log), "-o", str(out), "--force", "--no-register",
                              "--resolution", "50"])
    assert res.exit_code == 0, res.output
    assert "raw odometry" in res.output and mapkit.load(out).scan.resolution == 50


def test_simulate_options_and_versions(runner, tmp_path) -> None:
    room = tmp_path / "room.map"
    room.write_text("2D-Map\nLINES\n0 0 6000 0\n6000 0 6000 4000\n6000 4000 0 4000\n0 4000 0 0\n")
    log = tmp_path / "room.2d"
    res = runner.invoke(cli, ["simulate", str(room), "-o", str(log), "--version", "2",
                              "--waypoints", "1000,1000 5000,3000", "--no-truth", "--fov", "240"])
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "room.truth.tsv").exists()
    assert "version: 2" in log.read_text().splitlines()[:4]
    res = runner.invoke(cli, ["simulate", str(room), "-o", str(log), "--force",
                              "--waypoints", "1000,1000,5"])
    assert res.exit_code == 2 and "--waypoints: expected 2 numbers" in res.output
    res = runner.invoke(cli, ["simulate", "-o", str(log)])
    assert res.exit_code == 2 and "MAP_FILE or --sample" in res.output


def test_bad_log_is_one_line_error(runner, tmp_path) -> None:
    bad = tmp_path / "bad.2d"
    bad.write_text("LaserOdometryLog\nversion: 4\nsick1conf: -90 90 2\n"
                   "scanId: 0\nrobot: 0 0 0\nscan1: 1 2 3 \n")
    res = runner.invoke(cli, ["build", str(bad), "-o", str(tmp_path / "x.map")])
    assert res.exit_code == 1
    assert "bad.2d:6: scan1: odd number of values (3)" in res.output
    assert "Traceback" not in res.output
    res = runner.invoke(cli, ["log-info", str(bad), "--tolerant"])
    assert res.exit_code == 0 and "MK704" in res.output
    res = runner.invoke(cli, ["log-info", str(bad)])
    assert res.exit_code == 1 and "bad.2d:6:" in res.output
