"""Hostile frames on a real roscore: one unauthenticated message nested 100,000 deep used to
kill `mapkit ros serve` and `mapkit ros receive`. Now no message ends a robot node (deep JSON,
fuzzed frames, 500 handshakes never finished), and it still serves an honest terminal."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from tests.ros.conftest import Ros

pytestmark = pytest.mark.ros

SECRET = "hostile tests share this secret, 32 bytes"
HOSTILE = Path(__file__).with_name("hostile_peer.py")


@pytest.fixture(scope="module")
def net(ros: Ros) -> Ros:
    ros.env["MAPKIT_SECRET"] = SECRET
    return ros


def _robot(net: Ros, folder: Path, command: str, channel: str) -> object:
    before = net.topics()
    where = [str(folder)] if command == "serve" else ["-o", str(folder)]
    proc = net.start_mapkit(
        "ros", command, *where, "--name", f"{command}1", "--channel", channel, "--map-server", ""
    )
    net.wait_for(
        f"ros {command} to announce",
        lambda: proc.poll() is not None or f"/mapkit/{channel}/announce" in net.topics() - before,
    )
    assert proc.poll() is None, net.output(proc)
    return proc


@pytest.mark.parametrize("command", ["serve", "receive"])
def test_hostile_frames_do_not_end_a_robot_node(net: Ros, tmp_path: Path, command: str) -> None:
    channel = f"hostile_{command}"
    folder = tmp_path / "robot"
    folder.mkdir()
    proc = _robot(net, folder, command, channel)
    deep = net.run([sys.executable, str(HOSTILE), channel, "deep", "1", "0"], timeout=60)
    assert deep.stdout.startswith("sent"), deep.stdout + deep.stderr
    fuzz = net.run([sys.executable, str(HOSTILE), channel, "fuzz", "7", "24"], timeout=120)
    assert fuzz.stdout.startswith("sent"), fuzz.stdout + fuzz.stderr
    flood = net.run([sys.executable, str(HOSTILE), channel, "flood", "0", "500"], timeout=120)
    assert flood.stdout.startswith("sent 500"), flood.stdout + flood.stderr
    assert proc.poll() is None, net.output(proc)  # type: ignore[attr-defined]
    # an honest terminal is still served
    src = tmp_path / "after.map"
    src.write_text("2D-Map\nDATA\n1 2\n3 4\n")
    rows = json.loads(net.mapkit("ros", "send", str(src), "--channel", channel, "--json").stdout)
    assert rows[0]["ok"], rows
    assert (folder / "after.map").read_bytes() == src.read_bytes()
    out = net.output(proc)  # type: ignore[arg-type]
    assert "Traceback" not in out and "internal error" not in out, out[-3000:]
