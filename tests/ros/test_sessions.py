"""The ROS session drivers over an in-memory bus with injected faults (no roscore needed).

The same :class:`~mapkit.ros.transfer.RobotNode` and :class:`~mapkit.ros.transfer.Terminal`
that run over ROS topics, with a bus that loses, repeats and corrupts messages: whatever the
pattern, a pushed or pulled file arrives byte for byte, or the transfer fails cleanly and
nothing appears under the file's name.
"""

from __future__ import annotations

import hashlib
import os
import queue
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from mapkit.ros.transfer import FEATURES_SERVE, Robot, RobotNode, Terminal
from mapkit.ros.transport import Faults
from mapkit.transfer import MapFolder
from mapkit.transfer.protocol import FrameType, Offer

SECRET = b"in-memory bus secret, 32 bytes.."


class Bus:
    """Nodes by name; a message to a node lands in its inbox (through its faults)."""

    def __init__(self) -> None:
        self.links: dict[str, Link] = {}

    def link(self, node: str, faults: Faults | None = None) -> Link:
        self.links[node] = Link(self, node, faults)
        return self.links[node]


class Link:
    """What RobotNode and Terminal need of a RosLink."""

    def __init__(self, bus: Bus, node: str, faults: Faults | None) -> None:
        self.bus, self.node, self.faults = bus, node, faults
        self.channel = "test"
        self.inbox: queue.Queue[tuple[str, bytes]] = queue.Queue()
        self.announced: dict[str, Any] = {}

    def send(self, to: str, frame: bytes) -> None:
        dest = self.bus.links.get(to)
        if dest is None:
            return
        for item in dest.faults.apply(frame) if dest.faults else [frame]:
            dest.inbox.put((self.node, item))

    def receive(self, timeout: float | None) -> tuple[str, bytes] | None:
        try:
            return self.inbox.get(timeout=timeout) if timeout else self.inbox.get_nowait()
        except queue.Empty:
            return None

    def announce(self, doc: dict[str, Any]) -> None:
        self.announced = doc


class RobotThread:
    def __init__(self, node: RobotNode) -> None:
        self.node = node
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            self.node.step(0.02)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)


def robot_on(
    bus: Bus, folder: Path, name: str = "r1", faults: Faults | None = None, **kw: Any
) -> tuple[RobotThread, Robot]:
    node = RobotNode(
        MapFolder(folder),
        bus.link(f"/{name}", faults),
        robot=name,
        secret=SECRET,
        features=FEATURES_SERVE,
        map_server=None,
        rto=0.05,
        **kw,
    )
    return RobotThread(node), Robot(name, f"/{name}", list(FEATURES_SERVE), node.announcement())


@pytest.fixture
def bus() -> Iterator[Bus]:
    yield Bus()


def terminal(
    bus: Bus, name: str = "/term", faults: Faults | None = None, secret: bytes = SECRET, **kw: Any
) -> Terminal:
    return Terminal(
        bus.link(name, faults),
        secret,
        peer=name,
        rto=0.05,
        idle_timeout=kw.pop("idle_timeout", 5.0),
        **kw,
    )


@settings(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    data=st.binary(min_size=0, max_size=120_000),
    chunk=st.sampled_from([1024, 4096, 32768]),
    drop=st.floats(0, 0.25),
    dup=st.floats(0, 0.25),
    corrupt=st.floats(0, 0.1),
    seed=st.integers(0, 2**16),
)
def test_push_under_any_faults_is_exact_or_clean(
    tmp_path_factory: pytest.TempPathFactory,
    data: bytes,
    chunk: int,
    drop: float,
    dup: float,
    corrupt: float,
    seed: int,
) -> None:
    bus = Bus()
    folder = tmp_path_factory.mktemp("rx")
    rt, robot = robot_on(bus, folder, faults=Faults(drop, dup, corrupt, seed))
    try:
        term = terminal(bus, faults=Faults(drop, dup, corrupt, seed + 1))
        offer = Offer.for_bytes("f.2d", data, chunk_size=chunk)
        (res,) = term.push([robot], data, offer)
    finally:
        rt.close()
    target = folder / "f.2d"
    if res.ok:
        assert target.read_bytes() == data
    else:  # a clean failure: nothing under the name, the reason said
        assert not target.exists() and res.error
    assert not [p for p in os.listdir(folder) if not p.startswith(".") and p != "f.2d"]


def test_fleet_push_then_load_and_list(bus: Bus, tmp_path: Path, shared_dir: Path) -> None:
    sample = (shared_dir / "real" / "aria-office.map").read_bytes()
    robots = [
        robot_on(bus, tmp_path / f"r{i}", f"r{i}", Faults(0.1, 0.1, 0.02, i)) for i in range(3)
    ]
    try:
        term = terminal(bus, faults=Faults(0.1, 0.1, 0.02, 9))
        offer = Offer.for_bytes("office.map", sample, chunk_size=512)
        results = term.push([r for _, r in robots], sample, offer, load=True)
        rows = [(r.robot, r.verified, r.loaded) for r in results]
        assert rows == [(f"r{i}", True, True) for i in range(3)]
        for i in range(3):
            assert (tmp_path / f"r{i}" / "office.map").read_bytes() == sample
            assert (tmp_path / f"r{i}" / "active.map").read_bytes() == sample
        listing = term.request(robots[1][1], FrameType.LIST, {}, [FrameType.LISTING]).json()
        assert listing["active"] == "office.map"
        assert [m["md5"] for m in listing["maps"]] == [hashlib.md5(sample).hexdigest()]
        assert robots[0][0].node.link.announced["robot"] == "r0"  # re-announced after the push
    finally:
        for rt, _ in robots:
            rt.close()


def test_pull_under_faults_and_not_modified(bus: Bus, tmp_path: Path) -> None:
    data = os.urandom(300_000)
    (tmp_path / "robot").mkdir()
    (tmp_path / "robot" / "big.2d").write_bytes(data)
    rt, robot = robot_on(bus, tmp_path / "robot", faults=Faults(0.15, 0.15, 0.05, 3))
    try:
        term = terminal(bus, faults=Faults(0.15, 0.15, 0.05, 4))
        dest = tmp_path / "here" / "copy.2d"
        got = term.fetch(robot, "big.2d", str(dest), chunk_size=8192)
        assert got["changed"] and dest.read_bytes() == data
        again = term.fetch(robot, "big.2d", str(dest))
        assert not again["changed"]
        with pytest.raises(Exception, match="no such map"):
            term.fetch(robot, "missing.2d", str(tmp_path / "x.2d"))
        assert not (tmp_path / "x.2d").exists()
    finally:
        rt.close()


def test_wrong_secret_is_refused_quickly(bus: Bus, tmp_path: Path) -> None:
    rt, robot = robot_on(bus, tmp_path)
    try:
        term = terminal(bus, secret=b"some other secret of 32 bytes...")
        (res,) = term.push([robot], b"x" * 10, Offer.for_bytes("a.2d", b"x" * 10))
        assert not res.ok and "secret" in str(res.error)
        assert os.listdir(tmp_path) == []
    finally:
        rt.close()


def test_a_restarted_sender_takes_over_and_resumes(bus: Bus, tmp_path: Path) -> None:
    data = os.urandom(400_000)
    offer = Offer.for_bytes("big.2d", data, chunk_size=4096)
    rt, robot = robot_on(bus, tmp_path)
    try:
        # the first sender dies after about half the chunks (it stops reading its link)
        first = terminal(bus, "/sender", idle_timeout=0.5)
        sent = {"n": 0}
        orig = first.link.send

        def dying_send(to: str, frame: bytes) -> None:
            if len(frame) > 5 and frame[5] == FrameType.DATA:
                sent["n"] += 1
                if sent["n"] > offer.chunks // 2:
                    return
            orig(to, frame)

        first.link.send = dying_send  # type: ignore[method-assign]
        (res1,) = first.push([robot], data, offer)
        assert not res1.ok
        assert not (tmp_path / "big.2d").exists()
        # the same terminal restarted (same peer name): it takes the partial file over and resumes
        second = terminal(bus, "/sender")
        (res2,) = second.push([robot], data, offer)
        assert res2.ok and res2.resumed_chunks > 0, res2
        assert (tmp_path / "big.2d").read_bytes() == data
    finally:
        rt.close()


def test_a_repeated_load_is_answered_once(bus: Bus, tmp_path: Path, shared_dir: Path) -> None:
    sample = shared_dir / "real" / "aria-triangle.map"
    (tmp_path / "a.map").write_bytes(sample.read_bytes())
    (tmp_path / "b.map").write_bytes(sample.read_bytes())
    # the robot's answers are often lost: the terminal repeats LOAD, the robot must not load twice
    rt, robot = robot_on(bus, tmp_path)
    try:
        term = terminal(bus, faults=Faults(drop=0.5, seed=11))
        state = term.request(robot, FrameType.LOAD, {"name": "a.map"}, [FrameType.LOADED]).json()
        assert state["name"] == "a.map" and state["previous"] is None
        state = term.request(robot, FrameType.LOAD, {"name": "b.map"}, [FrameType.LOADED]).json()
        assert state["previous"]["name"] == "a.map"  # not b.map: each LOAD ran once
    finally:
        rt.close()


def test_a_clean_link_needs_no_resend(bus: Bus, tmp_path: Path) -> None:
    data = os.urandom(1_000_000)
    rt, robot = robot_on(bus, tmp_path)
    try:
        (res,) = terminal(bus).push([robot], data, Offer.for_bytes("m.2d", data, chunk_size=65536))
        assert res.ok and res.chunks_resent == 0 and res.chunks_sent == 16
    finally:
        rt.close()
