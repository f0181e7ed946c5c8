"""Reading a ROS map YAML as yaml-cpp reads it: bounded, with numbers and fields checked, errors
naming the file and line."""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mapkit._typing import PathLike
from mapkit.raster.errors import RosMapError
from mapkit.raster.ros.common import MODES, Flavor

__all__ = ["MAX_YAML_BYTES", "MAX_YAML_DEPTH", "MAX_YAML_NODES", "RosMapInfo", "read_ros_yaml"]


# -- reading -------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class RosMapInfo:
    """A map YAML as map_server reads it.

    Attributes:
        source: The YAML file.
        image: The ``image`` value as written.
        image_path: The image file (relative names resolved against the YAML's folder).
        resolution: Metres per pixel.
        origin: ``(x, y, yaw)`` of the lower-left pixel.
        negate: 0 or 1.
        occupied_thresh: Occupied threshold.
        free_thresh: Free threshold.
        mode: ``trinary`` (the default when absent), ``scale`` or ``raw``.
    """

    source: Path
    image: str
    image_path: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: int
    occupied_thresh: float
    free_thresh: float
    mode: str


_INT = re.compile(r"[-+]?(?:0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)")
_FLOAT = re.compile(r"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
_SPECIAL_FLOATS = {
    **{s + v: math.inf for s in ("", "+") for v in (".inf", ".Inf", ".INF")},
    **{"-" + v: -math.inf for v in (".inf", ".Inf", ".INF")},
    **{v: math.nan for v in (".nan", ".NaN", ".NAN")},
}
#: Largest map YAML read (a real one is a few hundred bytes).
MAX_YAML_BYTES = 1 << 16
#: Deepest nesting of lists and mappings read (composing recurses once per level).
MAX_YAML_DEPTH = 64
#: Most YAML values read (a real map YAML has about 15); bounds the time composing takes.
MAX_YAML_NODES = 4096


def _as_int(text: str) -> int | None:
    """A 32-bit integer as yaml-cpp reads one (C++ stream, base from the prefix), else ``None``.

    Examples:
        >>> [_as_int(t) for t in ("1", "010", "0x1F", "-0", "09", "1.0", "true", "9" * 5000)]
        [1, 8, 31, 0, None, None, None, None]
    """
    t = text.strip()
    if len(t) > 40 or not _INT.fullmatch(t):  # overflows long before 40 characters
        return None
    body = t.lstrip("+-")
    value = (
        int(body, 16)
        if body[:2] in ("0x", "0X")
        else int(body, 8)
        if body[:1] == "0"
        else int(body)
    )
    value = -value if t.startswith("-") else value
    return value if -(1 << 31) <= value < (1 << 31) else None


def _as_float(text: str) -> float | None:
    """A double as yaml-cpp reads one (``.inf``, ``.nan``; overflow fails), else ``None``.

    Examples:
        >>> [_as_float(t) for t in ("5e-2", "-.inf", "1e309", "0x10", "1" * 5000 + "x")]
        [0.05, -inf, None, None, None]
    """
    t = text.strip()
    if t in _SPECIAL_FLOATS:
        return _SPECIAL_FLOATS[t]
    if not _FLOAT.fullmatch(t):  # linear: no nested or overlapping repeats
        return None
    value = float(t)
    return value if math.isfinite(value) else None  # the C++ stream fails on overflow


def _compose(data: bytes, src: str) -> Any:
    """The YAML node graph (aliases are not expanded; recursion and size are bounded)."""
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    try:
        text = data.decode("utf-8-sig")
        depth = nodes = 0
        for event in yaml.parse(text, Loader=loader):  # no recursion: the nesting is bounded
            if isinstance(event, yaml.NodeEvent):
                nodes += 1
                if nodes > MAX_YAML_NODES:
                    raise RosMapError(f"not a map YAML: over {MAX_YAML_NODES:,} values", source=src)
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    mark = event.start_mark
                    raise RosMapError(
                        f"not a map YAML: nested over {MAX_YAML_DEPTH} levels",
                        source=src,
                        line=None if mark is None else mark.line + 1,
                    )
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1
        return yaml.compose(text, Loader=loader)
    except (yaml.YAMLError, UnicodeDecodeError) as err:
        line = getattr(getattr(err, "problem_mark", None), "line", None)
        raise RosMapError(
            f"not valid YAML: {err}".splitlines()[0],
            source=src,
            line=None if line is None else line + 1,
        ) from err


def read_ros_yaml(path: PathLike, *, flavor: Flavor = "ros1") -> RosMapInfo:
    """Read a map YAML by map_server's rules (keys, types, relative image path).

    ``negate`` must be an integer for ROS 1 (Nav2 also takes ``true``/``false``); ``origin`` needs
    at least 3 numbers (exactly 3 for Nav2); ``mode`` is case-sensitive; numbers may be quoted or
    use exponents; extra keys are ignored. Numbers are read as yaml-cpp does (a value the C++
    stream cannot hold, such as ``1e309`` or a 5,000-digit integer, is refused); a key given twice
    and non-finite thresholds are refused (map_server's result would be undefined).

    Raises:
        RosMapError: Naming the file and line of what map_server would reject.
    """
    import yaml

    from mapkit.raster.ros_image import open_regular

    p = Path(os.fspath(path))
    src = str(p)
    with open_regular(p, "map YAML") as fh:
        try:
            text = fh.read(MAX_YAML_BYTES + 1)
        except OSError as err:
            raise RosMapError(f"cannot read: {err.strerror or err}", source=src) from err
    if len(text) > MAX_YAML_BYTES:
        raise RosMapError(f"not a map YAML: larger than {MAX_YAML_BYTES:,} bytes", source=src)
    node = _compose(text, src)
    if not isinstance(node, yaml.MappingNode):
        raise RosMapError(
            "a map YAML is a mapping of keys (image, resolution, origin, ...)", source=src, line=1
        )
    keys: dict[str, Any] = {}
    for k, v in node.value:
        if isinstance(k, yaml.ScalarNode):
            if k.value in keys:
                raise RosMapError(
                    f"key {k.value!r} is given twice (lines "
                    f"{keys[k.value].start_mark.line + 1} and "
                    f"{k.start_mark.line + 1})",
                    source=src,
                    line=k.start_mark.line + 1,
                )
            keys[k.value] = v

    def need(key: str) -> Any:
        if key not in keys:
            raise RosMapError(
                f"missing required key {key!r} (map_server fails with 'bad conversion')", source=src
            )
        return keys[key]

    def scalar(key: str) -> tuple[str, int]:
        v = need(key)
        line = v.start_mark.line + 1
        if not isinstance(v, yaml.ScalarNode):
            raise RosMapError(f"{key} must be a single value", source=src, line=line)
        return v.value, line

    def number(key: str) -> float:
        value, line = scalar(key)
        f = _as_float(value)
        if f is None:
            raise RosMapError(f"{key} must be a number, got {value!r}", source=src, line=line)
        return f

    image, line = scalar("image")
    if not image:
        raise RosMapError("the image tag cannot be an empty string", source=src, line=line)
    resolution = number("resolution")
    if not (math.isfinite(resolution) and resolution > 0):
        raise RosMapError(
            f"resolution must be a positive number, got {resolution!r}",
            source=src,
            line=keys["resolution"].start_mark.line + 1,
        )
    onode = need("origin")
    oline = onode.start_mark.line + 1
    if not isinstance(onode, yaml.SequenceNode):
        raise RosMapError("origin must be a list [x, y, yaw]", source=src, line=oline)
    nums = [_as_float(n.value) if isinstance(n, yaml.ScalarNode) else None for n in onode.value]
    if any(n is None for n in nums):
        raise RosMapError("origin must hold numbers", source=src, line=oline)
    if len(nums) < 3 or (flavor == "nav2" and len(nums) != 3):
        need_n = "exactly 3" if flavor == "nav2" else "at least 3"
        raise RosMapError(
            f"origin needs {need_n} numbers (x, y, yaw), got {len(nums)}", source=src, line=oline
        )
    ox, oy, yaw = (float(n) for n in nums[:3])  # type: ignore[arg-type]
    if not all(math.isfinite(v) for v in (ox, oy, yaw)):
        raise RosMapError("origin must be finite", source=src, line=oline)
    nvalue, nline = scalar("negate")
    negate = _as_int(nvalue)
    if negate is None and flavor == "nav2" and nvalue.strip().lower() in ("true", "false"):
        negate = int(nvalue.strip().lower() == "true")
    if negate is None:
        raise RosMapError(
            f"negate must be an integer 0 or 1, got {nvalue!r} (map_server reads it as an int)",
            source=src,
            line=nline,
        )
    occ = number("occupied_thresh")
    free = number("free_thresh")
    for key, value in (("occupied_thresh", occ), ("free_thresh", free)):
        if not math.isfinite(value):
            raise RosMapError(
                f"{key} must be a finite number, got {value!r} (map_server's result is undefined)",
                source=src,
                line=keys[key].start_mark.line + 1,
            )
    mode = "trinary"
    if "mode" in keys:
        mvalue, mline = scalar("mode")
        if mvalue not in MODES:
            raise RosMapError(
                f"mode must be trinary, scale or raw (case-sensitive), got {mvalue!r}",
                source=src,
                line=mline,
            )
        mode = mvalue
    if mode == "scale" and occ == free:
        raise RosMapError(
            f"scale mode divides by occupied_thresh - free_thresh, which is 0 here ({occ!r})",
            source=src,
            line=keys["free_thresh"].start_mark.line + 1,
        )
    img_path = Path(image) if os.path.isabs(image) else p.parent / image
    return RosMapInfo(
        p, image, img_path, resolution, (ox, oy, yaw), int(negate != 0), occ, free, mode
    )
