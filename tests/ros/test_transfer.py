"""Map transfer over a real roscore between separate processes (`python -m mapkit ros ...`).

Push to one robot and to a fleet of three, pull/list/load against `mapkit ros serve` (with a
map server following the loads, checked with `rostopic`), injected drops/duplicates/corruption,
and a receiver killed in the middle of a transfer.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.ros.conftest import Ros

pytestmark = pytest.mark.ros

SECRET = "ros tests share this secret, 32 bytes"


@pytest.fixture(scope="module")
def net(ros: Ros) -> Ros:
    """The module's roscore, with the shared secret in the environment of every process."""
    ros.env["MAPKIT_SECRET"] = SECRET
    return ros


def big_file(path: Path, size: int, seed: int = 0) -> Path:
    """A .2d-named file of pseudo-random text lines (any bytes would do; .2d is not parsed)."""
    import random

    rng = random.Random(seed)
    lines, n = [], 0
    while n < size:
        line = f"{rng.randrange(-(10**6), 10**6)} {rng.randrange(-(10**6), 10**6)}\n"
        lines.append(line)
        n += len(line)
    path.write_bytes("".join(lines).encode()[:size])
    return path


def announcers(net: Ros, channel: str) -> int:
    """Nodes the master lists as publishing the channel's announcement."""
    import xmlrpc.client

    state = xmlrpc.client.ServerProxy(net.uri).getSystemState("/pytest")[2][0]
    return sum(len(nodes) for topic, nodes in state if topic == f"/mapkit/{channel}/announce")


def start_receiver(
    net: Ros,
    out: Path,
    name: str,
    *args: str,
    env: dict[str, str] | None = None,
    channel: str = "maps",
) -> subprocess.Popen[bytes]:
    before = announcers(net, channel)
    proc = net.start_mapkit(
        "ros",
        "receive",
        "-o",
        str(out),
        "--name",
        name,
        "--channel",
        channel,
        *args,
        env=env or net.env,
    )
    net.wait_for(
        f"receiver {name} to announce itself",
        lambda: proc.poll() is not None or announcers(net, channel) > before,
    )
    assert proc.poll() is None, net.output(proc)
    return proc


def send(
    net: Ros,
    path: Path,
    *args: str,
    check: bool = True,
    env: dict[str, str] | None = None,
    timeout: float = 120,
) -> subprocess.CompletedProcess[str]:
    return net.mapkit(
        "ros", "send", str(path), *args, check=check, env=env or net.env, timeout=timeout
    )


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def visible(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))


# -- push ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def solo(
    net: Ros, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, subprocess.Popen[bytes]]:
    out = tmp_path_factory.mktemp("solo")
    return out, start_receiver(net, out, "solo", channel="solo")


def test_push_one_robot_byte_identical(net: Ros, solo: Any, real_sample: Path) -> None:
    out, rx = solo
    res = send(net, real_sample, "--channel", "solo", "--json")
    rows = json.loads(res.stdout)
    got = [(r["robot"], r["received"], r["verified"], r["ok"]) for r in rows]
    assert got == [("solo", True, True, True)]
    assert (out / real_sample.name).read_bytes() == real_sample.read_bytes()
    assert real_sample.name in visible(out) and not any(".mkpart" in n for n in visible(out))
    net.wait_for("the receiver's report", lambda: f"received {real_sample.name}" in net.output(rx))


def test_receive_count_exits_after_the_files(net: Ros, tmp_path: Path, shared_dir: Path) -> None:
    sample = shared_dir / "real" / "aria-triangle.map"
    rx = start_receiver(net, tmp_path, "once", "--count", "1", "--json", channel="once")
    send(net, sample, "--channel", "once")
    assert rx.wait(30) == 0, net.output(rx)
    assert json.loads(net.output(rx)[net.output(rx).index("[") :])[0]["name"] == sample.name


def test_fleet_of_three_with_load(net: Ros, tmp_path: Path, shared_dir: Path) -> None:
    sample = shared_dir / "real" / "aria294-columbia.map"
    robots = {f"r{i}": tmp_path / f"r{i}" for i in (1, 2, 3)}
    procs = [
        net.start_mapkit("ros", "receive", "-o", str(d), "--name", n, "--channel", "fleet")
        for n, d in robots.items()
    ]  # started together; `send --expect 3` waits for all
    res = send(net, sample, "--channel", "fleet", "--expect", "3", "--wait", "60", "--load")
    lines = res.stdout.splitlines()
    assert lines[0].split() == ["robot", "received", "verified", "loaded", "note"]
    assert [ln.split()[:4] for ln in lines[1:]] == [[n, "yes", "yes", "yes"] for n in robots]
    for d in robots.values():
        assert (d / sample.name).read_bytes() == sample.read_bytes()
        assert (d / "active.map").read_bytes() == sample.read_bytes()
    # the same file again: every robot verifies again, nothing fails
    again = json.loads(send(net, sample, "--channel", "fleet", "--expect", "3", "--json").stdout)
    assert [r["ok"] for r in again] == [True] * 3
    for p in procs:
        os.killpg(p.pid, signal.SIGINT)
    for p in procs:
        assert p.wait(30) == 0, net.output(p)


@pytest.fixture
def one_sample(shared_dir: Path) -> Path:
    return shared_dir / "real" / "aria291-columbia.map"


def test_send_fails_when_a_named_robot_is_missing(
    net: Ros, tmp_path: Path, one_sample: Path
) -> None:
    real_sample = one_sample
    start_receiver(net, tmp_path / "a", "present", channel="partial")
    res = send(
        net,
        real_sample,
        "--channel",
        "partial",
        "--robot",
        "present",
        "--robot",
        "absent",
        "--wait",
        "1",
        check=False,
    )
    assert res.returncode == 1
    assert "missing: absent" in res.stderr
    assert not (tmp_path / "a" / real_sample.name).exists()


def test_wrong_secret_is_refused_and_nothing_written(
    net: Ros, tmp_path: Path, one_sample: Path
) -> None:
    real_sample = one_sample
    out = tmp_path / "locked"
    start_receiver(net, out, "locked", channel="locked")
    env = dict(net.env, MAPKIT_SECRET="another secret, also long enough")
    res = send(net, real_sample, "--channel", "locked", "--json", check=False, env=env)
    assert res.returncode == 1
    (row,) = json.loads(res.stdout)
    assert not row["verified"] and "secret" in row["error"]
    assert visible(out) == []
    res = send(
        net,
        real_sample,
        "--channel",
        "locked",
        "--insecure",
        "--json",
        check=False,
        env={k: v for k, v in net.env.items() if k != "MAPKIT_SECRET"},
    )
    assert res.returncode == 1 and "requires authentication" in json.loads(res.stdout)[0]["error"]


# -- faults ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [1, 2])
def test_drops_duplicates_and_corruption_still_byte_identical(
    net: Ros, tmp_path: Path, seed: int
) -> None:
    data = big_file(tmp_path / "scan.2d", 1_500_000, seed)
    out = tmp_path / "lossy"
    faults = f"drop=0.1,dup=0.1,corrupt=0.05,seed={seed}"
    env = dict(net.env, MAPKIT_ROS_FAULTS=faults)
    rx = start_receiver(net, out, "lossy", "--count", "1", env=env, channel=f"lossy{seed}")
    res = send(
        net,
        data,
        "--channel",
        f"lossy{seed}",
        "--chunk-size",
        "16384",
        "--json",
        env=dict(net.env, MAPKIT_ROS_FAULTS=f"drop=0.1,dup=0.1,corrupt=0.05,seed={seed + 10}"),
    )
    (row,) = json.loads(res.stdout)
    assert row["ok"] and row["chunks_resent"] > 0, row  # losses happened and were repaired
    assert rx.wait(30) == 0, net.output(rx)
    assert sha(out / "scan.2d") == sha(data)


def test_every_chunk_corrupted_fails_cleanly(net: Ros, tmp_path: Path) -> None:
    data = big_file(tmp_path / "doomed.2d", 200_000)
    out = tmp_path / "bad"
    env = dict(net.env, MAPKIT_ROS_FAULTS="corrupt=1,only_data=1")
    start_receiver(net, out, "bad", env=env, channel="doomed")
    res = send(net, data, "--channel", "doomed", "--chunk-size", "16384", "--json", check=False)
    assert res.returncode == 1
    (row,) = json.loads(res.stdout)
    assert not row["verified"] and "not acknowledged" in row["error"]
    assert visible(out) == []


def test_receiver_killed_mid_transfer_leaves_nothing_then_resumes(net: Ros, tmp_path: Path) -> None:
    data = big_file(tmp_path / "long.2d", 8_000_000, 7)
    out = tmp_path / "killed"
    # the link dies after 150 of the 489 chunks: the robot is surely in the middle when killed
    env = dict(net.env, MAPKIT_ROS_FAULTS="stall_after=150")
    rx = start_receiver(net, out, "victim", env=env, channel="victim")
    sender = net.start_mapkit(
        "ros",
        "send",
        str(data),
        "--channel",
        "victim",
        "--chunk-size",
        "16384",
        "--timeout",
        "3",
        "--json",
    )
    net.wait_for(
        "chunks on disk and in the resume journal",
        lambda: (out / ".long.2d.mkpart.json").exists() or sender.poll() is not None,
        timeout=60,
    )
    assert sender.poll() is None, net.output(sender) + net.output(rx)
    os.killpg(rx.pid, signal.SIGKILL)
    rx.wait(10)
    assert not (out / "long.2d").exists() and visible(out) == []
    assert sender.wait(60) == 1  # the sender reports the robot as failed
    row = json.loads(net.output(sender)[net.output(sender).index("[") :])[0]
    assert not row["verified"] and not row["received"]
    # the robot comes back: the next run completes, resuming what was on disk
    rx2 = start_receiver(net, out, "victim", "--count", "1", channel="victim")
    res = send(net, data, "--channel", "victim", "--chunk-size", "16384", "--json")
    (row,) = json.loads(res.stdout)
    assert row["ok"] and 0 < row["resumed_chunks"] <= 150, row
    assert row["chunks_sent"] == 489 - row["resumed_chunks"]  # only the missing chunks crossed
    assert rx2.wait(30) == 0
    assert sha(out / "long.2d") == sha(data)
    assert visible(out) == ["long.2d"]


# -- serve: pull, list, load ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def robot(net: Ros, tmp_path_factory: pytest.TempPathFactory, shared_dir: Path) -> dict[str, Any]:
    folder = tmp_path_factory.mktemp("robot_maps")
    for name in ("aria-office.map", "aria-triangle.map"):
        (folder / name).write_bytes((shared_dir / "real" / name).read_bytes())
    server = net.start_mapkit(
        "ros", "map-server", str(folder / "aria-triangle.map"), "--resolution", "0.1"
    )
    serve = net.start_mapkit("ros", "serve", str(folder), "--name", "robot1", "--channel", "robot")
    wanted = {"/change_map", "/mapkit/robot/announce"}
    net.wait_for("serve and map-server", lambda: wanted <= net.topics() | net.services())
    return {"folder": folder, "serve": serve, "server": server}


def test_list_pull_and_load_through_serve(
    net: Ros, robot: dict[str, Any], tmp_path: Path, shared_dir: Path
) -> None:
    folder = robot["folder"]
    listing = json.loads(net.mapkit("ros", "maps", "--channel", "robot", "--json").stdout)
    assert listing["robot"] == "robot1"
    names = ("aria-office.map", "aria-triangle.map")
    assert {m["name"]: m["md5"] for m in listing["maps"]} == {
        n: hashlib.md5((folder / n).read_bytes()).hexdigest() for n in names
    }

    dest = tmp_path / "pulled.map"
    got = json.loads(
        net.mapkit(
            "ros", "fetch", "aria-office.map", "-o", str(dest), "--channel", "robot", "--json"
        ).stdout
    )
    assert got["changed"] and dest.read_bytes() == (folder / "aria-office.map").read_bytes()
    again = json.loads(
        net.mapkit(
            "ros",
            "fetch",
            "aria-office.map",
            "-o",
            str(dest),
            "--channel",
            "robot",
            "--if-changed",
            "--json",
        ).stdout
    )
    assert not again["changed"]
    missing = net.mapkit("ros", "fetch", "nope.map", "--channel", "robot", check=False)
    assert missing.returncode == 1 and "no such map" in missing.stderr

    def width() -> int:
        out = net.run(["rostopic", "echo", "-n1", "/map_metadata"]).stdout
        return int(yaml.safe_load(out.split("\n---")[0])["width"])

    before = width()
    res = net.mapkit("ros", "load", "aria-office.map", "--channel", "robot")
    assert "active map on robot1 is now aria-office.map" in res.stdout
    assert "map server republished /map" in res.stdout
    assert (folder / "active.map").read_bytes() == (folder / "aria-office.map").read_bytes()
    import mapkit
    from mapkit.raster.rasterize import rasterize

    expect = rasterize(mapkit.load(shared_dir / "real" / "aria-office.map"), 0.1).width
    assert width() == expect != before
    bad = net.mapkit(
        "ros", "load", "aria-office.map", "--md5", "0" * 32, "--channel", "robot", check=False
    )
    assert bad.returncode == 1 and "md5" in bad.stderr.lower()
    listing = json.loads(net.mapkit("ros", "maps", "--all", "--channel", "robot", "--json").stdout)
    assert listing[0]["active"] == "aria-office.map"


def test_push_to_serve_then_pull_back(
    net: Ros, robot: dict[str, Any], tmp_path: Path, one_sample: Path
) -> None:
    real_sample = one_sample
    out = send(net, real_sample, "--channel", "robot", "--name", "pushed.map", "--json").stdout
    res = json.loads(out)
    assert res[0]["ok"]
    assert (robot["folder"] / "pushed.map").read_bytes() == real_sample.read_bytes()
    dest = tmp_path / "back.map"
    net.mapkit("ros", "fetch", "pushed.map", "-o", str(dest), "--channel", "robot")
    assert dest.read_bytes() == real_sample.read_bytes()
