"""``mapkit ros2 map-server`` and ``mapkit ros2 aria-bridge``: a map on ROS 2 as nav2 serves it.

Topics (all reliable, transient-local, keep-last 1, as nav2's map_server and
costmap_filter_info_server publish them, so late joiners get the current map):

=========================  ==============================  ========================================
topic                      type                            what
=========================  ==============================  ========================================
``/map`` (``--topic``)     nav_msgs/msg/OccupancyGrid      the grid
``/keepout_filter_mask``   nav_msgs/msg/OccupancyGrid      forbidden areas/lines 100, else -1
``/costmap_filter_info``   nav2_msgs/msg/CostmapFilterInfo type 0 (keepout), that mask, base 0, x1
``/map_goals``             geometry_msgs/msg/PoseArray     goals (any goal type)
``/map_homes``             geometry_msgs/msg/PoseArray     robot homes
``/map_docks``             geometry_msgs/msg/PoseArray     docks
=========================  ==============================  ========================================

A map_server YAML has no keepout mask or poses: only ``/map`` is published for it.
:func:`payloads` (what to publish, as bytes) is sans-I/O; :class:`Ros2MapServer` writes them.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from mapkit.ros.grids import MapLoadError, ServedMap, served_map
from mapkit.ros2.messages import (
    COSTMAP_FILTER_INFO,
    OCCUPANCY_GRID,
    POSE_ARRAY,
    costmap_filter_info_cdr,
    grid_cdr,
    pose_array_cdr,
)

__all__ = [
    "FileWatch",
    "Payload",
    "Ros2MapServer",
    "Topics",
    "payloads",
    "run_aria_bridge",
    "run_map_server",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Topics:
    """ROS 2 topic names of the map server (relative names resolve in the node's namespace)."""

    map: str = "map"
    keepout_mask: str = "keepout_filter_mask"
    filter_info: str = "costmap_filter_info"
    goals: str = "map_goals"
    homes: str = "map_homes"
    docks: str = "map_docks"


@dataclass(frozen=True)
class Payload:
    """One message to publish: ROS 2 topic, message type, CDR bytes."""

    topic: str
    typename: str
    cdr: bytes


def payloads(
    served: ServedMap,
    topics: Topics = Topics(),
    frame_id: str = "map",
    stamp: float | None = None,
    distro: str = "jazzy",
    namespace: str = "/",
) -> list[Payload]:
    """Everything the server publishes for one map, serialised (the grid first)."""
    from mapkit.ros2.graph import resolve_topic

    now = time.time() if stamp is None else stamp
    out = [Payload(topics.map, OCCUPANCY_GRID, grid_cdr(served.grid, frame_id, now, now, distro))]
    if served.keepout is not None:
        out.append(
            Payload(
                topics.keepout_mask,
                OCCUPANCY_GRID,
                grid_cdr(served.keepout, frame_id, now, now, distro),
            )
        )
        out.append(
            Payload(
                topics.filter_info,
                COSTMAP_FILTER_INFO,
                costmap_filter_info_cdr(
                    resolve_topic(topics.keepout_mask, namespace), frame_id, now, distro=distro
                ),
            )
        )
        for topic, poses in (
            (topics.goals, served.goals),
            (topics.homes, served.homes),
            (topics.docks, served.docks),
        ):
            out.append(Payload(topic, POSE_ARRAY, pose_array_cdr(poses, frame_id, now, distro)))
    return out


class FileWatch:
    """Notices when a file changes on disk (size, mtime or inode; then its bytes decide)."""

    def __init__(self, path: str) -> None:
        self.path = path
        self._sig = self._signature()

    def _signature(self) -> tuple[int, int, int] | None:
        try:
            st = os.stat(self.path)
        except OSError:
            return None
        return (st.st_size, st.st_mtime_ns, st.st_ino)

    def changed(self) -> bool:
        """True once after each change (a vanished file is no change: it may be being replaced)."""
        sig = self._signature()
        if sig is None or sig == self._sig:
            return False
        self._sig = sig
        return True


class Ros2MapServer:
    """Serve one map at a time on ROS 2 (topics in the module docstring).

    Args:
        node: The DDS node (:class:`mapkit.ros2.dds.Node`).
        path: The first map (``.map`` or map_server YAML).
        topics: Topic names.
        frame_id: Frame of every message.
        resolution: Metres per cell for ``.map`` files.
        **raster: More rasteriser options (``free`` ...).

    Raises:
        MapLoadError: When the first map cannot be loaded (nothing is published then).
    """

    def __init__(
        self,
        node: Any,
        path: str,
        *,
        topics: Topics = Topics(),
        frame_id: str = "map",
        resolution: float = 0.05,
        loaded: ServedMap | None = None,
        **raster: Any,
    ) -> None:
        self.node, self.topics, self.frame_id = node, topics, frame_id
        self.resolution, self.raster = resolution, raster
        self.current = loaded or served_map(path, resolution, **raster)
        self.published = 0

    def publish(self) -> None:
        """(Re)publish every topic for the active map."""
        for p in payloads(
            self.current,
            self.topics,
            self.frame_id,
            distro=self.node.distro,
            namespace=self.node.namespace,
        ):
            self.node.writer(p.topic, p.typename).write(p.cdr)
        self.published += 1

    def change(self, path: str) -> ServedMap:
        """Serve another map (or the same file's new contents); the old one stays on failure.

        Raises:
            MapLoadError: When it cannot be loaded.
        """
        self.current = served_map(path, self.resolution, **self.raster)
        self.publish()
        return self.current


def run_map_server(
    path: str,
    *,
    domain: int = 0,
    topics: Topics = Topics(),
    frame_id: str = "map",
    distro: str = "jazzy",
    node_name: str = "mapkit_map_server",
    stop: threading.Event | None = None,
    poll: float = 0.5,
    on_publish: Callable[[Ros2MapServer], None] | None = None,
    on_error: Callable[[MapLoadError], None] | None = None,
    **options: Any,
) -> Ros2MapServer:
    """Serve ``path`` on ROS 2 until ``stop`` is set; republish when the file changes on disk.

    A change that does not load (a half-written or broken file) keeps the previous map on the
    topics and is reported to ``on_error``; the next good version is published.

    Raises:
        MapLoadError: When the first map cannot be loaded.
        Ros2Error: When DDS cannot be joined.
    """
    from mapkit.ros2.dds import Node

    stop = stop or threading.Event()
    server_path = path[len("file://") :] if path.startswith("file://") else path
    resolution = options.pop("resolution", 0.05)
    first = served_map(server_path, resolution, **options)  # a bad file never joins DDS
    node = Node(node_name, domain, distro=distro)
    server = Ros2MapServer(
        node,
        server_path,
        topics=topics,
        frame_id=frame_id,
        resolution=resolution,
        loaded=first,
        **options,
    )
    server.publish()
    if on_publish is not None:
        on_publish(server)
    watch = FileWatch(server_path)
    while not stop.wait(poll):
        if not watch.changed():
            continue
        try:
            server.change(server_path)
        except MapLoadError as err:
            log.warning(
                "%s changed but does not load; still serving the previous map: %s", server_path, err
            )
            if on_error is not None:
                on_error(err)
            continue
        if on_publish is not None:
            on_publish(server)
    node.close()
    return server


def run_aria_bridge(
    robot: Any,
    *,
    domain: int = 0,
    topics: Topics = Topics(),
    frame_id: str = "map",
    distro: str = "jazzy",
    node_name: str = "mapkit_aria_bridge",
    stop: threading.Event | None = None,
    on_publish: Callable[[Ros2MapServer, Any], None] | None = None,
    **options: Any,
) -> int:
    """Serve an ArNetworking robot's active map on ROS 2, republished when the robot changes it.

    Args:
        robot: A connected :class:`mapkit.arnet.Robot` (closed by the caller).
        stop: Ends the bridge when set (checked twice a second).
        on_publish: Called after each publication with the server and the robot's change.

    Returns:
        The number of maps published.

    Raises:
        AriaError: When the robot cannot be read.
        MapLoadError: When the robot's map cannot be rasterised.
        Ros2Error: When DDS cannot be joined.
    """
    from mapkit.ros.aria_bridge import robot_maps
    from mapkit.ros2.dds import Node

    stop = stop or threading.Event()
    node = Node(node_name, domain, distro=distro)
    server: Ros2MapServer | None = None
    served = 0
    try:
        for path, change in robot_maps(robot, stop.is_set):
            if server is None:
                server = Ros2MapServer(node, path, topics=topics, frame_id=frame_id, **options)
                server.publish()
            else:
                server.change(path)
            served += 1
            log.info("serving %s from %s (MD5 %s) on ROS 2", change.name, robot.address, change.md5)
            if on_publish is not None:
                on_publish(server, change)
    finally:
        node.close()
    return served
