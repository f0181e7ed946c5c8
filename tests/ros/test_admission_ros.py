"""The robot node's limits on sessions that never authenticate, and a sender resuming the same
transfer, over the in-memory bus of test_sessions (the same RobotNode that runs on ROS topics)."""

from __future__ import annotations

import os
import time
from pathlib import Path

from mapkit.transfer.protocol import Channel, FrameType, Offer, Out, dump_json
from tests.ros.test_sessions import Bus, robot_on, terminal


def _hello(session: int) -> bytes:
    c = Channel(initiator=True, session=session, ordered=False)
    return c.encode(
        Out(
            FrameType.HELLO,
            dump_json({"versions": [1], "nonce": "ab" * 32, "auth": ["blake2b"], "peer": "flood"}),
        )
    )


def test_a_hello_flood_is_bounded_and_expires(tmp_path: Path) -> None:
    bus = Bus()
    rt, robot = robot_on(bus, tmp_path, handshake_timeout=0.5, per_node=4, max_pending=8)
    node = rt.node
    try:
        flood = bus.link("/flood")
        for i in range(1000):  # never AUTH
            flood.send(robot.node, _hello(i + 1))
        end = time.monotonic() + 30  # the robot has handled every one (a queue, not a limit)
        while time.monotonic() < end and not node.link.inbox.empty():
            time.sleep(0.01)
        assert node.admission.pending("/flood") <= 4
        assert len(node.sessions) <= 8 + 4  # pending, plus failed ones about to go
        # an honest terminal is served meanwhile
        data = os.urandom(5000)
        (res,) = terminal(bus).push([robot], data, Offer.for_bytes("a.2d", data, chunk_size=1024))
        assert res.ok and (tmp_path / "a.2d").read_bytes() == data
        end = time.monotonic() + 10  # and the flood's sessions go at their deadline
        while time.monotonic() < end and node.admission.pending("/flood"):
            time.sleep(0.02)
        assert node.admission.pending("/flood") == 0 and node.admission.timed_out >= 1
    finally:
        rt.close()


def test_the_same_file_from_a_new_sender_takes_over_at_once(tmp_path: Path, monkeypatch) -> None:
    """A terminal restarted after a cut (a new node name) offers the same file: the robot's old
    session, not silent long enough to count as stale, gives way to it at once."""
    import threading

    import mapkit.ros.transfer.robot as robot_side

    monkeypatch.setattr(robot_side, "STALE", 1000.0)  # only the same-transfer rule can apply
    bus = Bus()
    rt, robot = robot_on(bus, tmp_path)
    try:
        data = os.urandom(64 * 1024)
        offer = Offer.for_bytes("scan.2d", data, chunk_size=1024)
        first = terminal(bus, "/laptop-before", idle_timeout=3.0)
        link = bus.links["/laptop-before"]
        real_send = link.send
        sent = {"data": 0}

        def cut(to: str, frame: bytes) -> None:  # the Wi-Fi drops after 10 chunks
            if len(frame) > 5 and frame[5] == FrameType.DATA:
                sent["data"] += 1
            if sent["data"] <= 10:
                real_send(to, frame)

        link.send = cut  # type: ignore[method-assign]
        t = threading.Thread(target=lambda: first.push([robot], data, offer), daemon=True)
        t.start()
        end = time.monotonic() + 10
        while time.monotonic() < end and sent["data"] <= 10:
            time.sleep(0.01)
        other = os.urandom(64 * 1024)  # another file for the name: busy
        (busy,) = terminal(bus, "/someone").push(
            [robot], other, Offer.for_bytes("scan.2d", other, chunk_size=1024)
        )
        assert not busy.ok and "busy" in (busy.error or "")
        (res,) = terminal(bus, "/laptop-after").push([robot], data, offer)
        assert res.ok, res.error
        assert (tmp_path / "scan.2d").read_bytes() == data
        t.join(10)
    finally:
        rt.close()


def test_long_names_are_bad_names_on_every_ros_request(tmp_path: Path) -> None:
    import pytest

    from mapkit.errors import RemoteTransferError

    bus = Bus()
    rt, robot = robot_on(bus, tmp_path)
    try:
        term = terminal(bus)
        for name in ("a" * 252 + ".map", "é" * 120 + ".map", "c" * 198 + ".2d"):  # > 200 bytes
            data = b"2D-Map\nDATA\n1 2\n"
            (res,) = term.push([robot], data, Offer.for_bytes(name, data))
            assert not res.ok and "bad_name" in (res.error or ""), res.error
            for ftype, payload, answers in (
                (FrameType.GET, {"name": name}, [FrameType.OFFER]),
                (FrameType.LOAD, {"name": name, "md5": "0" * 32}, [FrameType.LOADED]),
            ):
                with pytest.raises(RemoteTransferError, match="bad_name"):
                    term.request(robot, ftype, payload, answers)
        assert term.request(robot, FrameType.LIST, {}, [FrameType.LISTING]).json()["maps"] == []
    finally:
        rt.close()
    assert os.listdir(tmp_path) == []


def test_the_robot_node_deletes_abandoned_partial_files(tmp_path: Path) -> None:
    old = time.time() - 3 * 86400
    for name in (".lost.map.mkpart", ".lost.map.mkpart.json", ".fresh.2d.mkpart"):
        (tmp_path / name).write_bytes(b"{}")
    for name in (".lost.map.mkpart", ".lost.map.mkpart.json"):
        os.utime(tmp_path / name, (old, old))
    bus = Bus()
    rt, _ = robot_on(bus, tmp_path)
    try:
        end = time.monotonic() + 10
        while time.monotonic() < end and (tmp_path / ".lost.map.mkpart").exists():
            time.sleep(0.02)
    finally:
        rt.close()
    assert sorted(os.listdir(tmp_path)) == [".fresh.2d.mkpart"]


def test_an_unexpected_error_ends_only_its_ros_session(tmp_path: Path, caplog) -> None:
    import pytest

    from mapkit.errors import RemoteTransferError

    bus = Bus()
    from tests.transfer.mkt_helpers import fails_once

    rt, robot = robot_on(bus, tmp_path)
    rt.node.folder.listing = fails_once(
        rt.node.folder.listing,  # type: ignore[method-assign]
        RuntimeError("a bug"),
    )
    try:
        term = terminal(bus)
        with pytest.raises(RemoteTransferError, match="internal"):
            term.request(robot, FrameType.LIST, {}, [FrameType.LISTING])
        assert "RuntimeError: a bug" in caplog.text
        assert rt.thread.is_alive()
        listing = term.request(robot, FrameType.LIST, {}, [FrameType.LISTING]).json()
        assert listing["maps"] == []
    finally:
        rt.close()
