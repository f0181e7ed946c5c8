"""Object types a map declares (``MapInfo:``) and the per-object parameters (``CairnInfo: Params``).

FORMATS.md A.6.3: ``MapInfo: <Class> Name=<type> Key=Value ...`` declares a type; the ``ArgDesc``
lines after it (``Parent=<type>``) declare its parameters, and ``CairnInfo: Params "<object>"
v1 v2 ...`` gives one object's values in ``ArgDesc`` order. ARIA looks a ``Params`` line up by
object name (case-insensitive) and keeps the lines in alphabetical order of name when it edits
them; mapkit does the same and leaves every other info line where it is.
"""

from __future__ import annotations

import math
import types
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from mapkit.edit.checks import check_text
from mapkit.errors import EditError
from mapkit.formats._numbers import aria_double
from mapkit.model import InfoLine, MapData, MapObject

__all__ = [
    "BUILTIN_CLASSES",
    "ArgSpec",
    "object_params",
    "params_for_new_object",
    "rename_params",
    "shape_of_class",
    "type_args",
    "type_class",
    "type_key",
    "with_params",
    "without_params",
]

#: ARIA's built-in types and the class they behave as (``RobotHome`` may be a point or a rectangle).
BUILTIN_CLASSES: Mapping[str, str] = types.MappingProxyType(
    {
        "Goal": "GoalType",
        "GoalWithHeading": "GoalType",
        "Dock": "DockType",
        "RobotHome": "RobotHome",
        "ForbiddenLine": "BoundaryType",
        "ForbiddenArea": "SectorType",
    }
)

_POINT_CLASSES = ("GoalType", "DockType", "LocationType")


def shape_of_class(cls: str | None) -> str | None:
    """``"point"``, ``"line"``, ``"rect"`` for a type class, ``None`` when either fits or unknown.

    Examples:
        >>> shape_of_class("SectorType"), shape_of_class("BoundaryType"), shape_of_class("DockType")
        ('rect', 'line', 'point')
    """
    if cls in _POINT_CLASSES:
        return "point"
    if cls == "BoundaryType":
        return "line"
    if cls == "SectorType":
        return "rect"
    return None


def unquote(tok: str) -> str:
    """A token without its surrounding quotes."""
    return tok[1:-1] if len(tok) >= 2 and tok[0] == tok[-1] == '"' else tok


def _kv(line: InfoLine) -> dict[str, str]:
    out: dict[str, str] = {}
    for tok in line[1:]:
        t = unquote(tok)
        k, sep, v = t.partition("=")
        if sep:
            out.setdefault(k, v)
    return out


def type_class(m: MapData, type: str) -> str | None:
    """The class a type behaves as: declared in ``MapInfo:``, built in, or ``None`` (undeclared).

    A point type ``XWithHeading`` has the class of ``X`` (FORMATS.md A.7.3).

    Examples:
        >>> from mapkit.formats.map import loads
        >>> m = loads("2D-Map\\nMapInfo: SectorType Name=Slow\\n"
        ...           "MapInfo: GoalType Name=Door\\nDATA\\n")
        >>> [type_class(m, t) for t in ("Slow", "DoorWithHeading", "Dock", "X")]
        ['SectorType', 'GoalType', 'DockType', None]
    """
    declared = m.declared_types()
    if type in declared:
        return declared[type]
    if type in BUILTIN_CLASSES:
        return BUILTIN_CLASSES[type]
    suffix = "WithHeading"
    if type.endswith(suffix) and len(type) > len(suffix):
        base = declared.get(type[: -len(suffix)])
        if base in ("GoalType", "DockType"):
            return base
    return None


def type_key(m: MapData, type: str, key: str) -> str | None:
    """A key of a type's declaration (``NameRequired``, ``Heading``, ...), or ``None``."""
    for line in m.info.get("MapInfo", ()):
        if line and line[0].endswith("Type") and _kv(line).get("Name") == type:
            return _kv(line).get(key)
    return None


@dataclass(frozen=True)
class ArgSpec:
    """One parameter of a type (a ``MapInfo: ArgDesc`` line).

    Attributes:
        name: Parameter name.
        kind: ``int``, ``double``, ``bool`` or ``string``.
        default: The ``Value=`` (or a neutral value when the line has none).
        min: ``Min=`` as a number, if any.
        max: ``Max=`` as a number, if any.
    """

    name: str
    kind: str
    default: str
    min: float | None = None
    max: float | None = None

    def token(self, value: Any) -> str:
        """Check a value and give the token ARIA stores (strings quoted, numbers and bools bare).

        Examples:
            >>> ArgSpec("WaitTime", "int", "10", 0, 100).token("25")
            '25'
            >>> ArgSpec("WaitTime", "int", "10", 0, 100).token(250)
            Traceback (most recent call last):
            ...
            mapkit.errors.EditError: parameter WaitTime = 250 is above its maximum 100
        """
        text = str(value).strip() if not isinstance(value, bool) else ("true" if value else "false")
        if self.kind == "string":
            return '"' + check_text(str(value), f"parameter {self.name}") + '"'
        if self.kind == "bool":
            low = text.lower()
            if low not in ("true", "false", "1", "0"):
                raise EditError(f"parameter {self.name} must be true or false, got {value!r}")
            return "true" if low in ("true", "1") else "false"
        try:
            num = int(text) if self.kind == "int" else float(text)
        except ValueError:
            raise EditError(
                f"parameter {self.name} must be "
                f"{'an integer' if self.kind == 'int' else 'a number'}, "
                f"got {value!r}"
            ) from None
        if not math.isfinite(num):
            raise EditError(f"parameter {self.name} must be finite, got {value!r}")
        if self.min is not None and num < self.min:
            raise EditError(f"parameter {self.name} = {text} is below its minimum {self.min:g}")
        if self.max is not None and num > self.max:
            raise EditError(f"parameter {self.name} = {text} is above its maximum {self.max:g}")
        return str(num) if self.kind == "int" else text


def _bound(v: str | None) -> float | None:
    if v is None:
        return None
    f = aria_double(v)  # read from the file: as ARIA reads it
    return f if f is not None and math.isfinite(f) else None


def type_args(m: MapData, type: str) -> list[ArgSpec]:
    """The parameters (``ArgDesc`` lines with ``Parent=<type>``) of a type, in order.

    Examples:
        >>> from mapkit.formats.map import loads
        >>> m = loads("2D-Map\\nMapInfo: SectorType Name=Door\\n"
        ...           "MapInfo: ArgDesc Name=Wait Parent=Door Type=int Value=10 Min=0\\nDATA\\n")
        >>> type_args(m, "Door")
        [ArgSpec(name='Wait', kind='int', default='10', min=0.0, max=None)]
    """
    out = []
    for line in m.info.get("MapInfo", ()):
        if not line or line[0] != "ArgDesc":
            continue
        kv = _kv(line)
        if kv.get("Parent") != type or "Name" not in kv:
            continue
        kind = kv.get("Type", "string").lower()
        if kind not in ("int", "double", "bool", "string"):
            kind = "string"
        neutral = {"int": "0", "double": "0", "bool": "false", "string": ""}[kind]
        out.append(
            ArgSpec(
                kv["Name"],
                kind,
                kv.get("Value", neutral),
                _bound(kv.get("Min")),
                _bound(kv.get("Max")),
            )
        )
    return out


def _args_type(m: MapData, type: str) -> str:
    """The type whose ``ArgDesc`` lines apply: ``X`` for an undeclared ``XWithHeading``."""
    declared = m.declared_types()
    suffix = "WithHeading"
    if type not in declared and type.endswith(suffix) and type[: -len(suffix)] in declared:
        return type[: -len(suffix)]
    return type


def _is_params(line: InfoLine) -> bool:
    return len(line) >= 2 and line[0] == "Params"


def _params_index(lines: tuple[InfoLine, ...], name: str) -> int | None:
    low = name.lower()
    for i, line in enumerate(lines):
        if _is_params(line) and unquote(line[1]).lower() == low:
            return i
    return None


def params_for_new_object(
    m: MapData, type: str, name: str, values: Mapping[str, Any] | None
) -> tuple[str, ...] | None:
    """The ``Params`` line for a new object: given values, the rest from the defaults.

    Returns ``None`` when the type has no parameters (and none were given).

    Raises:
        EditError: Unknown parameter names, bad values, or values for an unnamed object (ARIA
            keys ``Params`` by name).
    """
    specs = type_args(m, _args_type(m, type))
    values = dict(values or {})
    if not specs:
        if values:
            raise EditError(
                f"type {type!r} declares no parameters (no MapInfo: ArgDesc with "
                f"Parent={type}); got {', '.join(sorted(values))}"
            )
        return None
    known = {s.name.lower(): s for s in specs}
    unknown = [k for k in values if k.lower() not in known]
    if unknown:
        raise EditError(
            f"unknown {'parameter' if len(unknown) == 1 else 'parameters'} "
            f"{', '.join(unknown)} for type {type!r}; it has "
            f"{', '.join(s.name for s in specs)}"
        )
    if not name:
        if values:
            raise EditError(
                f"parameters need a named object: ARIA finds them by name (type {type!r})"
            )
        return None
    given = {k.lower(): v for k, v in values.items()}
    tokens = []
    for s in specs:
        if s.name.lower() in given:
            tokens.append(s.token(given[s.name.lower()]))
        else:
            tokens.append(s.token(s.default) if s.kind != "string" else f'"{s.default}"')
    return ("Params", f'"{name}"', *tokens)


def with_params(m: MapData, line: tuple[str, ...]) -> MapData:
    """Insert (or replace) a ``CairnInfo: Params`` line, keeping ``Params`` lines in name order."""
    name = unquote(line[1])
    lines = list(m.info.get("CairnInfo", ()))
    i = _params_index(tuple(lines), name)
    if i is not None:
        lines[i] = line
    else:
        pos = len(lines)
        last_params = None
        for j, existing in enumerate(lines):
            if _is_params(existing):
                last_params = j
                if unquote(existing[1]).lower() > name.lower():
                    pos = j
                    break
        else:
            if last_params is not None:
                pos = last_params + 1
        lines.insert(pos, line)
    info = dict(m.info)
    info["CairnInfo"] = tuple(lines)
    return m.replace(info=info)


def without_params(m: MapData, name: str) -> MapData:
    """Drop the ``Params`` line of a name (when present)."""
    lines = m.info.get("CairnInfo", ())
    i = _params_index(lines, name)
    if i is None:
        return m
    info = dict(m.info)
    info["CairnInfo"] = lines[:i] + lines[i + 1 :]
    return m.replace(info=info)


def rename_params(m: MapData, old: str, new: str, *, keep_old: bool = False) -> MapData:
    """Give the ``Params`` line of ``old`` to ``new`` (moved to its place in name order)."""
    lines = m.info.get("CairnInfo", ())
    i = _params_index(lines, old)
    if i is None:
        return m
    line = ("Params", f'"{new}"', *lines[i][2:])
    base = m if keep_old else without_params(m, old)
    return with_params(base, line)


def object_params(m: MapData, obj: MapObject) -> dict[str, str]:
    """An object's parameter values by name (from its ``Params`` line, else the defaults)."""
    specs = type_args(m, _args_type(m, obj.type))
    if not specs:
        return {}
    values = {s.name: s.default for s in specs}
    lines = m.info.get("CairnInfo", ())
    i = _params_index(lines, obj.name) if obj.name else None
    if i is not None:
        for s, tok in zip(specs, lines[i][2:], strict=False):
            values[s.name] = unquote(tok)
    return values
