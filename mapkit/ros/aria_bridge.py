"""Bridge an ARNL/ARAM robot's active map into ROS: ``mapkit ros aria-bridge HOST``.

The robot is reached over ArNetworking (:mod:`mapkit.arnet`); its active map is fetched
(byte-exact where the user may read files, else from its map service), served on ROS exactly as
``mapkit ros map-server`` serves a file (latched ``map``, ``map_metadata``, ``keepout_mask``,
``map_goals``/``map_homes``/``map_docks``, ``map_info``, the ``static_map`` service; not
``change_map``: the robot decides which map is active), and
fetched and republished each time the robot broadcasts that its map changed.
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from typing import Any

from mapkit._atomic import atomic_write
from mapkit.arnet import MapChange, Robot
from mapkit.ros.map_server import MapServer
from mapkit.ros.node import rospy, start_node, stop_on_signals

__all__ = ["robot_maps", "run_aria_bridge"]

log = logging.getLogger(__name__)


def robot_maps(
    robot: Robot, stop: Callable[[], bool], tick: float = 0.5
) -> Iterator[tuple[str, MapChange]]:
    """The robot's active map now and after each change, each saved as a file to serve.

    Yields ``(path, change)``: ``path`` is ``change.data`` written atomically into a private
    folder under the map's own name (removed when the generator ends). Shared by the ROS 1
    and ROS 2 bridges.
    """
    workdir = tempfile.mkdtemp(prefix="mapkit-aria-bridge-")
    try:
        for change in robot.watch(stop=stop, tick=tick):
            path = os.path.join(workdir, os.path.basename(change.name) or "robot.map")
            atomic_write(path, change.data)
            yield path, change
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


def run_aria_bridge(
    robot: Robot,
    *,
    resolution: float = 0.05,
    frame_id: str = "map",
    node_name: str = "mapkit_aria_bridge",
    on_change: Callable[[MapServer, MapChange], None] | None = None,
    **raster: Any,
) -> int:
    """Serve ``robot``'s active map on ROS until Ctrl-C/SIGTERM; the number of maps served.

    Args:
        robot: A connected robot (see :func:`mapkit.arnet.connect`); closed by the caller.
        resolution: Metres per cell.
        frame_id: The frame of every message.
        node_name: The node's name (one bridge per namespace).
        on_change: Called after each (re)publication with the server and the change.
        **raster: More rasteriser options (``free`` ...).

    Raises:
        AriaError: When the robot cannot be read (it is not retried: run the bridge under a
            supervisor that restarts it, as ROS launch files do with ``respawn``).
        MapLoadError: When the robot's map cannot be rasterised.
        RosError: When no ROS master answers.
    """
    start_node(node_name, anonymous=False)
    stop_on_signals()
    rp = rospy()
    server: MapServer | None = None
    served = 0
    try:
        for path, change in robot_maps(robot, rp.is_shutdown):
            if server is None:
                server = MapServer(path, resolution=resolution, frame_id=frame_id, **raster)
                server.start(change_map=False)  # the robot decides which map is active
            else:
                server.change(path)
            served += 1
            log.info("serving %s from %s (MD5 %s)", change.name, robot.address, change.md5)
            if on_change is not None:
                on_change(server, change)
    except KeyboardInterrupt:
        pass
    finally:
        if server is not None:
            server.stop()
    return served
