"""An ARIA-aware ROS 1 map server: what ROS's ``map_server`` offers, fed from ``.map`` files.

In the node's namespace (names as ROS's map_server uses them, so navigation stacks find them):

=====================  ============================  ==============================================
name                   type                          what
=====================  ============================  ==============================================
``map``                nav_msgs/OccupancyGrid        latched; the active map's grid
``map_metadata``       nav_msgs/MapMetaData          latched; its size, resolution, origin
``static_map``         nav_msgs/GetMap (service)     the active grid
``change_map``         nav_msgs/LoadMap (service)    load a ``.map`` or map_server YAML; republish
``keepout_mask``       nav_msgs/OccupancyGrid        latched; forbidden areas/lines 100, else -1
``map_goals``          geometry_msgs/PoseArray       latched; goals (any goal type)
``map_homes``          geometry_msgs/PoseArray       latched; robot homes
``map_docks``          geometry_msgs/PoseArray       latched; docks
``map_info``           std_msgs/String               latched JSON: file, hashes, size, pose names
=====================  ============================  ==============================================

Every latched topic is republished when the active map changes (``change_map``, which
``mapkit ros load`` calls through ``mapkit ros serve``).
"""

from __future__ import annotations

import json
import logging
import threading
from typing import Any

from mapkit.ros.grids import (
    LOAD_SUCCESS,
    LOAD_UNDEFINED,
    MapLoadError,
    ServedMap,
    grid_message,
    metadata_message,
    packed_response,
    pose_array_message,
    served_map,
)
from mapkit.ros.node import ros_import, rospy

__all__ = ["MapServer", "map_info", "run_map_server"]

log = logging.getLogger(__name__)


def map_info(served: ServedMap) -> dict[str, Any]:
    """The JSON document of the ``map_info`` topic (and of ``mapkit ros map-server --json``)."""
    g = served.grid
    return {
        "file": served.path,
        "name": served.name,
        "sha256": served.sha256,
        "md5": served.md5,
        "width": g.width,
        "height": g.height,
        "resolution": g.resolution,
        "origin": list(g.origin),
        "yaw": served.yaw,
        "keepout": served.keepout is not None,
        "goals": [p.name for p in served.goals],
        "homes": [p.name for p in served.homes],
        "docks": [p.name for p in served.docks],
    }


class MapServer:
    """Serve one map at a time on ROS (see the module docstring for topics and services).

    Args:
        path: The first map (``.map`` or map_server YAML).
        resolution: Metres per cell for ``.map`` files.
        frame_id: The frame of every message.
        progress: Called as ``progress(rows, total)`` while the first map is made.
        raster: More options for the rasteriser (``free``, ``margin_m``, ``inflate_mm``).

    Raises:
        MapLoadError: When the first map cannot be loaded (nothing is advertised then).
    """

    def __init__(
        self,
        path: str,
        *,
        resolution: float = 0.05,
        frame_id: str = "map",
        progress: Any = None,
        **raster: Any,
    ) -> None:
        self.resolution = resolution
        self.frame_id = frame_id
        self.raster = raster
        self.current = served_map(path, resolution, progress=progress, **raster)
        self._lock = threading.Lock()
        self._pubs: dict[str, Any] = {}
        self._services: list[Any] = []
        self.changes = 0

    # -- ROS side ------------------------------------------------------------------------------

    def start(self, *, change_map: bool = True) -> None:
        """Advertise topics and services and publish the first map (the node must be started).

        Args:
            change_map: Also offer the ``change_map`` service (not when another source decides
                the active map, as in ``mapkit ros aria-bridge``).
        """
        rp = rospy()
        nav, gm = ros_import("nav_msgs.msg"), ros_import("geometry_msgs.msg")
        std, srv = ros_import("std_msgs.msg"), ros_import("nav_msgs.srv")
        latched = {
            "map": nav.OccupancyGrid,
            "map_metadata": nav.MapMetaData,
            "keepout_mask": nav.OccupancyGrid,
            "map_goals": gm.PoseArray,
            "map_homes": gm.PoseArray,
            "map_docks": gm.PoseArray,
            "map_info": std.String,
        }
        for name, cls in latched.items():
            self._pubs[name] = rp.Publisher(name, cls, latch=True, queue_size=1)
        self._services = [rp.Service("static_map", srv.GetMap, self._on_static_map)]
        if change_map:
            self._services.append(rp.Service("change_map", srv.LoadMap, self._on_change_map))
        self.publish()

    def stop(self) -> None:
        """Withdraw the topics and services."""
        for s in self._services:
            s.shutdown("mapkit map server stopping")
        for p in self._pubs.values():
            p.unregister()
        self._services, self._pubs = [], {}

    def publish(self) -> None:
        """(Re)publish every latched topic for the active map."""
        rp = rospy()
        std = ros_import("std_msgs.msg")
        with self._lock:
            cur = self.current
            now = rp.Time.now()
            self._load_time = now
            self._grid_msg = grid_message(cur.grid, self.frame_id, now, now, yaw=cur.yaw)
        pubs = self._pubs
        pubs["map_metadata"].publish(metadata_message(cur.grid, now, yaw=cur.yaw))
        pubs["map"].publish(self._grid_msg)
        if cur.keepout is not None:
            pubs["keepout_mask"].publish(grid_message(cur.keepout, self.frame_id, now, now))
        poses_by_topic = {"map_goals": cur.goals, "map_homes": cur.homes, "map_docks": cur.docks}
        for key, poses in poses_by_topic.items():
            pubs[key].publish(pose_array_message(poses, self.frame_id, now))
        pubs["map_info"].publish(std.String(data=json.dumps(map_info(cur))))

    def change(self, url: str) -> ServedMap:
        """Make another map the active one and republish; the active map stays on failure.

        Raises:
            MapLoadError: With the ``nav_msgs/LoadMap`` result code.
        """
        new = served_map(url, self.resolution, **self.raster)
        with self._lock:
            self.current = new
            self.changes += 1
        if self._pubs:
            self.publish()
        log.info("now serving %s (%d x %d cells)", new.path, new.grid.width, new.grid.height)
        return new

    def _on_static_map(self, _req: Any) -> Any:
        with self._lock:
            return packed_response("GetMap", self._grid_msg)

    def _on_change_map(self, req: Any) -> Any:
        srv = ros_import("nav_msgs.srv")
        try:
            self.change(req.map_url)
        except MapLoadError as err:
            log.warning("change_map %s refused: %s", req.map_url, err)
            return srv.LoadMapResponse(result=err.code)
        except Exception:  # a service must answer: anything unexpected is "undefined failure"
            log.exception("change_map %s failed", req.map_url)
            return srv.LoadMapResponse(result=LOAD_UNDEFINED)
        with self._lock:
            return packed_response("LoadMap", self._grid_msg, result=LOAD_SUCCESS)


def run_map_server(
    path: str,
    *,
    resolution: float = 0.05,
    frame_id: str = "map",
    node_name: str = "mapkit_map_server",
    on_ready: Any = None,
    progress: Any = None,
    **raster: Any,
) -> MapServer:
    """Start a node, serve ``path`` until Ctrl-C or SIGTERM, and return the server.

    Args:
        path: The first map (``.map`` or map_server YAML).
        resolution: Metres per cell for ``.map`` files.
        frame_id: The frame of every message.
        node_name: The node's name (not anonymous: one map server per namespace, like ROS's).
        on_ready: Called with the :class:`MapServer` once everything is advertised.
        progress: Called as ``progress(rows, total)`` while the first map is made.
        **raster: More rasteriser options.

    Raises:
        MapLoadError: When the first map cannot be loaded.
        RosError: When no ROS master answers.
    """
    from mapkit.ros.node import spin, start_node

    server = MapServer(path, resolution=resolution, frame_id=frame_id, progress=progress, **raster)
    start_node(node_name, anonymous=False)
    server.start()
    if on_ready is not None:
        on_ready(server)
    spin()
    server.stop()
    return server
