"""Publish several maps from one ROS 2 node (one DDS participant):
``python -m tests.ros2.publish_maps
DOMAIN MAP...``. Map i goes to topics map_i, keepout_i, filter_info_i, goals_i, homes_i, docks_i.
Prints ``PUBLISHED`` when every map is written, then serves until stdin closes."""

from __future__ import annotations

import sys

from mapkit.ros2.dds import Node
from mapkit.ros2.map_server import Ros2MapServer, Topics


def topics(i: int) -> Topics:
    return Topics(
        map=f"map_{i}",
        keepout_mask=f"keepout_{i}",
        filter_info=f"filter_info_{i}",
        goals=f"goals_{i}",
        homes=f"homes_{i}",
        docks=f"docks_{i}",
    )


def main() -> None:
    node = Node("mapkit_test_publisher", int(sys.argv[1]))
    for i, path in enumerate(sys.argv[2:]):
        Ros2MapServer(node, path, topics=topics(i)).publish()
    print("PUBLISHED", flush=True)
    sys.stdin.read()
    node.close()


if __name__ == "__main__":
    main()
