"""Who is on the channel: robots announce themselves on a latched topic; :func:`discover`
collects them."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from mapkit.ros.errors import RosError
from mapkit.ros.node import rospy, wait_until
from mapkit.ros.transport import DEFAULT_WINDOW, RosLink
from mapkit.transfer.protocol import (
    DEFAULT_CHUNK_SIZE,
)

__all__ = ["Robot", "Watcher", "discover"]


@dataclass
class Robot:
    """A robot node seen on the channel (from its latched announcement)."""

    robot: str
    node: str
    features: list[str]
    doc: dict[str, Any]


def _robot_from(doc: dict[str, Any]) -> Robot | None:
    if isinstance(doc.get("node"), str) and isinstance(doc.get("features"), list):
        features = [str(f) for f in doc["features"]]
        return Robot(str(doc.get("robot", doc["node"])), doc["node"], features, doc)
    return None


class Watcher:
    """A client link that collects robot announcements as they arrive (latched: late joiners
    see them too)."""

    def __init__(
        self, channel: str, *, window: int = DEFAULT_WINDOW, chunk_size: int = DEFAULT_CHUNK_SIZE
    ) -> None:
        self.robots: dict[str, Robot] = {}
        self.link = RosLink(
            channel, robot=False, window=window, chunk_size=chunk_size, on_announce=self._on
        )

    def _on(self, doc: dict[str, Any]) -> None:
        r = _robot_from(doc)
        if r is not None:
            self.robots[r.node] = r

    def publishers(self) -> int:
        """Nodes the master lists as publishing the announcement (stale ones included)."""
        rp = rospy()
        topic = rp.resolve_name(self.link.topics["announce"])
        try:
            pubs = rp.get_master().getSystemState()[2][0]
        except Exception:  # the master's answer is only a hint here
            return 0
        return sum(len(nodes) for name, nodes in pubs if name == topic)

    def wait(
        self,
        *,
        timeout: float,
        expect: int = 0,
        feature: str | None = None,
        names: Iterable[str] = (),
    ) -> list[Robot]:
        """Robots announced within ``timeout`` (sooner once every announcing node, or ``expect``
        of them, or all ``names``, were heard), filtered by ``feature`` and ``names``."""
        want = set(names)

        def pick() -> list[Robot]:
            rs = [r for r in self.robots.values() if feature is None or feature in r.features]
            return [r for r in rs if not want or r.robot in want]

        def enough() -> bool:
            got = pick()
            if want:
                return {r.robot for r in got} >= want
            if expect:
                return len(got) >= expect
            n = self.publishers()
            return bool(n) and len(self.robots) >= n

        wait_until(enough, timeout, 0.05)
        robots = sorted(pick(), key=lambda r: r.robot)
        # make sure the frame topics are connected to every robot before the first frame
        self.link.wait_connected(len(robots), timeout=5.0)
        return robots


def discover(
    channel: str, *, timeout: float = 3.0, feature: str | None = None
) -> list[dict[str, Any]]:
    """The announcements of the robot nodes on ``channel`` (the node must be started)."""
    w = Watcher(channel)
    try:
        return [r.doc for r in w.wait(timeout=timeout, feature=feature)]
    finally:
        w.link.close()


def _one_robot(w: Watcher, robot: str | None, feature: str, timeout: float) -> Robot:
    robots = w.wait(timeout=timeout, feature=feature, names=[robot] if robot else ())
    if not robots:
        who = f"robot {robot!r}" if robot else "robot node"
        raise RosError(
            f"no {who} serving {feature!r} on channel {w.link.channel!r} "
            f"(topic {rospy().resolve_name(w.link.topics['announce'])}); is "
            "`mapkit ros serve` running there?"
        )
    if len(robots) > 1:
        raise RosError(
            "several robots serve this channel: "
            + ", ".join(r.robot for r in robots)
            + "; choose one with --robot"
        )
    return robots[0]
