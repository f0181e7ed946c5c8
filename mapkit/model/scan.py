"""Records of a ``.2d`` laser log: the header, one :class:`LaserScan` per sweep, and events.

These are the in-memory form of ARIA's ``.2d`` logs (FORMATS.md part B), whatever the logger
version. Every value is in one convention, independent of the file's version:

* poses are :class:`Pose2D` (mm, mm, degrees); ``robot`` is the odometry pose, ``robot_global``
  the corrected one (v3+);
* a laser's mount is :attr:`LaserConfig.pose` in the robot frame, and its beams are described by
  :attr:`LaserConfig.start`, :attr:`LaserConfig.end` and :attr:`LaserConfig.count`: reading ``i`` of
  :attr:`LaserScan.ranges` is at ``start + i * (end - start) / (count - 1)`` degrees in the laser
  frame;
* :attr:`LaserScan.xy` holds the hit points of the ``scanK:`` line **in the laser frame** (x along
  the laser's forward axis), as version 4 writes them; ``(0, 0)`` marks a beam without a return.

The reader (:mod:`mapkit.formats.laser2d`) converts each version's conventions to these, and the
writer converts back. Each scan's data are numpy arrays: there is no Python object per reading.

Examples:
    >>> laser = LaserConfig(number=1, pose=Pose2D(100, 0, 90), start=-90, end=90, count=3)
    >>> s = LaserScan(scan_id=0, laser=1, robot=Pose2D(1000, 0, 90), xy=[[500, 0], [0, 0], [0, 0]])
    >>> s.valid.tolist()
    [True, False, False]
    >>> laser_to_robot(s.xy[s.valid], laser.pose).round(6).tolist()
    [[100.0, 500.0]]
    >>> s.global_points(laser).round(6).tolist()
    [[500.0, 100.0]]
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "LaserConfig",
    "LaserLog",
    "LaserScan",
    "LogEvent",
    "LogHeader",
    "LogRecord",
    "Pose2D",
    "compose",
    "invert",
    "laser_to_robot",
    "relative",
    "robot_to_world",
]

FloatArray = NDArray[np.float64]


class Pose2D(NamedTuple):
    """A planar pose: x and y in mm, theta in degrees (counter-clockwise)."""

    x: float
    y: float
    th: float


def _ro(a: Any, dtype: Any, shape_tail: tuple[int, ...]) -> np.ndarray[Any, Any] | None:
    if a is None:
        return None
    arr = np.array(a, dtype=dtype, copy=True)
    if arr.size == 0:
        arr = arr.reshape((0, *shape_tail))
    if arr.shape[1:] != shape_tail or arr.ndim != 1 + len(shape_tail):
        raise ValueError(
            f"expected an array of shape (N, {', '.join(map(str, shape_tail))}), got {arr.shape}"
        )
    arr.flags.writeable = False
    return arr


# -- pose arithmetic (vectorised: accepts (3,) or (N, 3) arrays, theta in degrees) ----------------


def compose(a: Any, b: Any) -> FloatArray:
    """The pose ``a ⊕ b``: ``b`` expressed in ``a``'s frame, moved to the world.

    Examples:
        >>> compose([1000, 0, 90], [100, 0, 0]).round(6).tolist()
        [1000.0, 100.0, 90.0]
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    t = np.radians(a[..., 2])
    c, s = np.cos(t), np.sin(t)
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    th = _wrap_deg(a[..., 2] + b[..., 2])
    return np.stack([x, y, th], axis=-1)


def invert(a: Any) -> FloatArray:
    """The inverse pose: ``compose(a, invert(a))`` is the identity.

    Examples:
        >>> compose([1000, 500, 30], invert([1000, 500, 30])).round(9).tolist()
        [0.0, 0.0, 0.0]
    """
    a = np.asarray(a, dtype=np.float64)
    t = np.radians(a[..., 2])
    c, s = np.cos(t), np.sin(t)
    x = -c * a[..., 0] - s * a[..., 1]
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack([x, y, _wrap_deg(-a[..., 2])], axis=-1) + 0.0


def relative(a: Any, b: Any) -> FloatArray:
    """The motion from pose ``a`` to pose ``b`` in ``a``'s frame (``invert(a) ⊕ b``)."""
    return compose(invert(a), b)


def _wrap_deg(t: Any) -> Any:
    return (np.asarray(t) + 180.0) % 360.0 - 180.0 + 0.0


def laser_to_robot(xy: Any, mount: Sequence[float]) -> FloatArray:
    """Laser-frame points to the robot frame through the laser's mount pose (FORMATS.md B.5).

    Args:
        xy: ``(N, 2)`` points in the laser frame.
        mount: The laser pose on the robot (x, y, theta degrees).

    Returns:
        ``(N, 2)`` float64 points in the robot frame.
    """
    p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    t = math.radians(mount[2])
    c, s = math.cos(t), math.sin(t)
    out = np.empty_like(p)
    out[:, 0] = mount[0] + c * p[:, 0] - s * p[:, 1]
    out[:, 1] = mount[1] + s * p[:, 0] + c * p[:, 1]
    return out


def robot_to_world(xy: Any, pose: Sequence[float]) -> FloatArray:
    """Robot-frame points to the world frame through a robot pose (same rule as the mount)."""
    return laser_to_robot(xy, pose)


# -- header ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class LaserConfig:
    """One laser as the header describes it (``sickKpose:``, ``sickKconf:``, ``sickKname:``).

    Attributes:
        number: The laser number ``K`` (1 is the primary laser).
        pose: Mount pose on the robot (mm, mm, degrees).
        start: Angle (degrees, laser frame) of reading 0 in :attr:`LaserScan.ranges`.
        end: Angle of the last reading.
        count: Number of readings per sweep (0 when the header does not say).
        name: The laser's name (v4), or ``""``.
        z: Mount height in mm from ``scanKpose:`` (v4), or ``None``.
    """

    number: int = 1
    pose: Pose2D = Pose2D(0.0, 0.0, 0.0)
    start: float = -90.0
    end: float = 90.0
    count: int = 0
    name: str = ""
    z: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", Pose2D(*(float(v) for v in self.pose)))

    @property
    def increment(self) -> float:
        """Degrees between two successive readings (negative when the angles decrease)."""
        return 0.0 if self.count < 2 else (self.end - self.start) / (self.count - 1)

    def angles(self, count: int | None = None) -> FloatArray:
        """Beam angles in degrees (laser frame), reading order (FORMATS.md B.2: divide by N-1).

        Examples:
            >>> LaserConfig(start=-90, end=90, count=5).angles().tolist()
            [-90.0, -45.0, 0.0, 45.0, 90.0]
        """
        n = self.count if count is None else count
        if n < 2:
            return np.full(max(n, 0), float(self.start))
        return np.linspace(self.start, self.end, n)


@dataclass(frozen=True, slots=True)
class LogHeader:
    """What a log says before its first record.

    Attributes:
        version: Logger version, 1 to 4 (FORMATS.md B.2).
        lasers: One :class:`LaserConfig` per laser, primary first.
        location_types: The ``locationTypes:`` list (v3+), e.g. ``("robot", "robotGlobal")``.
        use_encoder_pose: ``useEncoderPose:`` when given (documented, rarely written).
        comments: Comment lines of the header, without ``#`` (e.g. ``Created by ArLaserLogger``).
        extra: Unknown header lines, kept as read (text without the line end).
    """

    version: int = 4
    lasers: tuple[LaserConfig, ...] = (LaserConfig(),)
    location_types: tuple[str, ...] = ()
    use_encoder_pose: bool | None = None
    comments: tuple[str, ...] = ()
    extra: tuple[str, ...] = ()

    def laser(self, number: int = 1) -> LaserConfig:
        """The laser with this number (a default one, pose 0 and no count, when absent)."""
        for las in self.lasers:
            if las.number == number:
                return las
        return LaserConfig(number=number)


# -- records -----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class LaserScan:
    """One laser sweep and the robot's poses when it was taken.

    Attributes:
        scan_id: The record's ``scanId:`` (v4, from 0) or ``scan1Id:`` (v2/v3, from 1); the
            ``#scanN`` number in v1.
        laser: Laser number ``K`` (``scanK:`` line).
        robot: Odometry pose (``robot:``).
        time: Seconds (``logTime:``/``time:``), or ``None``.
        velocities: ``(vel mm/s, rotvel deg/s, latvel mm/s)``; ``latvel`` is ``nan`` in v2.
        robot_global: Corrected pose (``robotGlobal:``, v3+), or ``None``.
        robot_raw: Raw encoder pose (``robotRaw:`` / v2's ``#rawRobot:``), or ``None``.
        other_poses: Further location types: ``(name, pose or None)`` pairs in file order.
        xy: ``(N, 2)`` float64 hit points in the laser frame; ``(0, 0)`` = no return. ``None``
            when the record has only raw ranges (v1).
        ranges: ``(N,)`` float64 raw ranges (``sickK:``) in reading order, or ``None``.
        reflectors: ``(N,)`` int64 reflector values (``reflectorK:``), or ``None``.
        extra: Unknown lines inside the record, kept as read.
        line: Line number of the record's last line in the file (0 when not read from a file).
    """

    scan_id: int
    laser: int = 1
    robot: Pose2D = Pose2D(0.0, 0.0, 0.0)
    time: float | None = None
    velocities: tuple[float, float, float] | None = None
    robot_global: Pose2D | None = None
    robot_raw: Pose2D | None = None
    other_poses: tuple[tuple[str, Pose2D | None], ...] = ()
    xy: FloatArray | None = None
    ranges: FloatArray | None = None
    reflectors: NDArray[np.int64] | None = None
    extra: tuple[str, ...] = ()
    line: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "robot", Pose2D(*(float(v) for v in self.robot)))
        for name in ("robot_global", "robot_raw"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, Pose2D(*(float(c) for c in v)))
        object.__setattr__(self, "xy", _ro(self.xy, np.float64, (2,)))
        object.__setattr__(self, "ranges", _ro(self.ranges, np.float64, ()))
        object.__setattr__(self, "reflectors", _ro(self.reflectors, np.int64, ()))

    @property
    def num_readings(self) -> int:
        """Readings in the sweep (pairs on the ``scanK:`` line, else raw ranges)."""
        if self.xy is not None:
            return len(self.xy)
        return 0 if self.ranges is None else len(self.ranges)

    @property
    def valid(self) -> NDArray[np.bool_]:
        """Mask of the readings with a return (``xy`` not ``(0, 0)``; for raw ranges ``> 0``)."""
        if self.xy is not None:
            mask: NDArray[np.bool_] = np.any(self.xy != 0.0, axis=1)
            return mask
        if self.ranges is not None:
            return self.ranges > 0.0
        return np.zeros(0, dtype=bool)

    def laser_points(self, laser: LaserConfig, *, max_range: float | None = None) -> FloatArray:
        """The valid hit points in the laser frame, ``(K, 2)`` float64.

        From the ``scanK:`` pairs when present, else from the raw ranges and the laser's angles.

        Args:
            laser: The laser's configuration (for raw ranges).
            max_range: Drop readings at or beyond this range (mm); the laser's "no return" value
                (e.g. 32767) is dropped this way.
        """
        if self.xy is not None:
            p = self.xy[self.valid]
        elif self.ranges is not None:
            a = np.radians(laser.angles(len(self.ranges)))
            keep = self.ranges > 0.0
            r = self.ranges[keep]
            p = np.stack([r * np.cos(a[keep]), r * np.sin(a[keep])], axis=1)
        else:
            return np.zeros((0, 2))
        if max_range is not None and len(p):
            p = p[np.hypot(p[:, 0], p[:, 1]) < max_range]
        return p

    def robot_points(self, laser: LaserConfig, *, max_range: float | None = None) -> FloatArray:
        """The valid hit points in the robot frame (FORMATS.md B.5)."""
        return laser_to_robot(self.laser_points(laser, max_range=max_range), laser.pose)

    def global_points(
        self,
        laser: LaserConfig,
        *,
        pose: Sequence[float] | None = None,
        max_range: float | None = None,
    ) -> FloatArray:
        """The valid hit points in the world frame, through ``pose`` (default: the odometry
        pose)."""
        return robot_to_world(
            self.robot_points(laser, max_range=max_range), self.robot if pose is None else pose
        )

    def equals(self, other: LaserScan) -> bool:
        """Value equality (arrays compared element by element, NaN equal to NaN)."""
        if not isinstance(other, LaserScan):
            return False
        for name in ("xy", "ranges", "reflectors"):
            a, b = getattr(self, name), getattr(other, name)
            if (a is None) != (b is None):
                return False
            if a is not None and not np.array_equal(a, b):
                return False
        return (
            self.scan_id == other.scan_id
            and self.laser == other.laser
            and self.robot == other.robot
            and self.robot_global == other.robot_global
            and self.robot_raw == other.robot_raw
            and self.other_poses == other.other_poses
            and _same(self.time, other.time)
            and _same_tuple(self.velocities, other.velocities)
            and self.extra == other.extra
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LaserScan) and self.equals(other)

    __hash__ = None  # type: ignore[assignment]


def _same(a: float | None, b: float | None) -> bool:
    if a is None or b is None:
        return a is b
    return a == b or (math.isnan(a) and math.isnan(b))


def _same_tuple(a: tuple[float, ...] | None, b: tuple[float, ...] | None) -> bool:
    if a is None or b is None:
        return a is b
    return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))


@dataclass(frozen=True, slots=True)
class LogEvent:
    """A non-scan record: a goal, a loop marker, a tagged string or an info line (FORMATS.md B.4).

    Attributes:
        kind: ``"goal"`` (``cairn:``), ``"loop"`` (``loop: start|stop|end K`` or ``loop start K``),
            ``"tag"`` (any other line after ``time:`` and poses) or ``"info"`` (a line alone).
        text: The record's last line as read (e.g. ``cairn: GoalWithHeading "" ICON... "goal1"``).
        time: Seconds, or ``None``.
        robot: Odometry pose at the event, or ``None`` for info lines.
        robot_global: Corrected pose (v3+), or ``None``.
        robot_raw: Raw encoder pose, or ``None``.
        other_poses: Further location types, as on scans.
        name: Goal name (``goal1``) or loop tag (``1``).
        action: For loops: ``"start"``, ``"stop"`` or ``"end"`` (v2's word for stop).
        line: Line number of ``text`` in the file.
    """

    kind: str
    text: str
    time: float | None = None
    robot: Pose2D | None = None
    robot_global: Pose2D | None = None
    robot_raw: Pose2D | None = None
    other_poses: tuple[tuple[str, Pose2D | None], ...] = ()
    name: str = ""
    action: str = ""
    line: int = 0

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, LogEvent):
            return NotImplemented
        return all(
            getattr(self, f) == getattr(other, f)
            for f in (
                "kind",
                "text",
                "robot",
                "robot_global",
                "robot_raw",
                "other_poses",
                "name",
                "action",
            )
        ) and _same(self.time, other.time)

    __hash__ = None  # type: ignore[assignment]


LogRecord = LaserScan | LogEvent


@dataclass(frozen=True, slots=True, eq=False)
class LaserLog:
    """A whole log in memory: header and records in file order.

    For large logs prefer :func:`mapkit.formats.laser2d.iter_log`, which streams.

    Attributes:
        header: The header.
        records: Scans and events in file order.
        complete: The log ended with ``# End of log`` (the logger shut down cleanly).
        source: File name the log was read from.
    """

    header: LogHeader = field(default_factory=LogHeader)
    records: tuple[LogRecord, ...] = ()
    complete: bool = True
    source: str = "<memory>"

    def __post_init__(self) -> None:
        object.__setattr__(self, "records", tuple(self.records))

    @property
    def scans(self) -> list[LaserScan]:
        """The scans, in order."""
        return [r for r in self.records if isinstance(r, LaserScan)]

    @property
    def events(self) -> list[LogEvent]:
        """The events, in order."""
        return [r for r in self.records if isinstance(r, LogEvent)]

    def __iter__(self) -> Iterator[LogRecord]:
        return iter(self.records)

    def __len__(self) -> int:
        return len(self.records)

    def poses(self, which: str = "robot") -> FloatArray:
        """``(N, 3)`` poses of the scans: ``"robot"`` (odometry) or ``"robot_global"``.

        A scan without a corrected pose contributes its odometry pose.
        """
        rows = []
        for s in self.scans:
            p = (
                s.robot_global
                if which == "robot_global" and s.robot_global is not None
                else s.robot
            )
            rows.append(p)
        return np.array(rows, dtype=np.float64).reshape(-1, 3)

    def equals(self, other: LaserLog) -> bool:
        """Value equality of header, records and the end mark (the source is ignored)."""
        return (
            isinstance(other, LaserLog)
            and self.header == other.header
            and self.complete == other.complete
            and len(self.records) == len(other.records)
            and all(a == b for a, b in zip(self.records, other.records, strict=True))
        )

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LaserLog) and self.equals(other)

    __hash__ = None  # type: ignore[assignment]
