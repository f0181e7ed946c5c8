"""Goals from the log's ``cairn:`` events, placed at the corrected poses and merged."""

from __future__ import annotations

import math

import numpy as np

from mapkit.build._common import FloatArray, _rad
from mapkit.build._graph import between, then
from mapkit.formats.laser2d import goal_fields
from mapkit.model import MapObject
from mapkit.model.scan import LaserLog, LaserScan


def _obj_pose(p: FloatArray) -> tuple[float, float, float]:
    return float(round(p[0])), float(round(p[1])), float(round(math.degrees(p[2]), 1))


def _goals(
    log: LaserLog,
    scans: list[LaserScan],
    odo: FloatArray,
    est: FloatArray,
    pose_source: str,
    merge: bool = True,
) -> list[MapObject]:
    """``cairn:`` goal events as objects at their corrected poses.

    With ``merge``, the goals of one name (a tag given on every lap) become one object at the
    mean pose (headings averaged on the circle), where the name first appeared.
    """
    position = {id(s): k for k, s in enumerate(scans)}
    last = 0
    out: list[MapObject] = []
    for rec in log.records:
        if isinstance(rec, LaserScan):
            last = position.get(id(rec), last)
            continue
        if rec.kind != "goal" or rec.robot is None:
            continue
        pose = rec.robot_global if pose_source == "robotGlobal" and rec.robot_global else rec.robot
        g = _rad(np.array(pose, dtype=np.float64))
        # The goal's pose relative to the nearest scan's odometry, put on that scan's final pose.
        rel = between(odo[last], g)
        typ, desc, _icon, name = goal_fields(rec)
        out.append(MapObject(typ, *_obj_pose(then(est[last], rel)), name=name, description=desc))
    return _merge_goals(out) if merge else out


def _merge_goals(goals: list[MapObject]) -> list[MapObject]:
    """One object per (type, name) at the mean pose; unnamed goals are kept as they are."""
    groups: dict[tuple[str, str], list[MapObject]] = {}
    order: list[tuple[str, str] | int] = []
    for k, g in enumerate(goals):
        if not g.name:
            order.append(k)
            continue
        key = (g.type, g.name)
        if key not in groups:
            groups[key] = []
            order.append(key)
        groups[key].append(g)
    out = []
    for item in order:
        if isinstance(item, int):
            out.append(goals[item])
            continue
        grp = groups[item]
        if len(grp) == 1:
            out.append(grp[0])
            continue
        th = np.radians([g.theta for g in grp])
        mean = np.array(
            [
                np.mean([g.x for g in grp]),
                np.mean([g.y for g in grp]),
                math.atan2(float(np.sin(th).sum()), float(np.cos(th).sum())),
            ]
        )
        out.append(
            MapObject(
                grp[0].type, *_obj_pose(mean), name=grp[0].name, description=grp[0].description
            )
        )
    return out
