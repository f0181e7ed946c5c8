"""Log events with meaning: goals (``cairn:``) and loop markers."""

from __future__ import annotations

from mapkit.formats.map import tokenize
from mapkit.model.scan import (
    LogEvent,
    Pose2D,
)

__all__ = ["goal_event", "goal_fields", "loop_event"]


def goal_fields(event: LogEvent) -> tuple[str, str, str, str]:
    """``(type, description, icon, name)`` of a ``cairn:`` goal event (quotes removed).

    Examples:
        >>> e = goal_event("goal1", Pose2D(0, 0, 0))
        >>> e.text
        'cairn: GoalWithHeading "" ICON_GOALWITHHEADING "goal1"'
        >>> goal_fields(e)
        ('GoalWithHeading', '', 'ICON_GOALWITHHEADING', 'goal1')
    """
    toks = tokenize(event.text.split(":", 1)[1] if ":" in event.text else "")
    toks = [t[1:-1] if len(t) >= 2 and t[0] == t[-1] == '"' else t for t in toks]
    toks += [""] * (4 - len(toks))
    return toks[0] or "GoalWithHeading", toks[1], toks[2], " ".join(toks[3:]).strip()


def goal_event(
    name: str,
    robot: Pose2D,
    *,
    time: float | None = None,
    robot_global: Pose2D | None = None,
    type: str = "GoalWithHeading",
) -> LogEvent:
    """A goal event as ARIA's logger writes it (``cairn: GoalWithHeading "" ICON_... "name"``)."""
    icon = "ICON_" + type.upper()
    return LogEvent(
        "goal",
        f'cairn: {type} "" {icon} "{name}"',
        time=time,
        robot=Pose2D(*robot),
        robot_global=None if robot_global is None else Pose2D(*robot_global),
        name=name,
    )


def loop_event(
    action: str,
    tag: str,
    robot: Pose2D,
    *,
    time: float | None = None,
    robot_global: Pose2D | None = None,
) -> LogEvent:
    """A loop marker (``loop: start 1`` / ``loop: stop 1``) as the robot's microcontroller logs
    it."""
    if action not in ("start", "stop", "end"):
        raise ValueError(f"loop action must be start, stop or end, not {action!r}")
    return LogEvent(
        "loop",
        f"loop: {action} {tag}",
        time=time,
        robot=Pose2D(*robot),
        robot_global=None if robot_global is None else Pose2D(*robot_global),
        name=tag,
        action=action,
    )
