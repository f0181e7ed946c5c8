"""A batch of edits from a YAML or JSON file, applied to a map as one change.

The file is a list of edits, or a mapping with an ``edits:`` list. Each edit names its
operation (the CLI command's name) and gives its arguments, in either of two spellings::

    edits:
      - add-goal: {name: Kitchen, x: 1000, y: 2000, heading: 90}
      - op: forbid
        area: [0, 0, 2000, 1000]
        angle: 30
        rotate-about-centre: true
      - remove: {names: [Old desk]}
      - erase: {box: [-500, -500, 500, 500]}
      - transform: {rotate: 90, translate: [1000, 0]}

Argument names are the CLI's option names (``-`` or ``_`` alike). Regions are ``box: [x1, y1,
x2, y2]`` or ``polygon: [[x, y], ...]``; ``merge`` takes ``other:``, a map path relative to the
script. Every edit is checked as it is applied to the previous one's result; the first refusal
stops the batch with a message naming the file, the edit and (for YAML) its line, and nothing
is written.

Examples:
    >>> from mapkit.model import MapData
    >>> edits = parse_script('[{"add-goal": {"name": "A", "x": 0, "y": 0}},'
    ...                      ' {"op": "rename", "name": "A", "new-name": "B"}]')
    >>> [e.op for e in edits]
    ['add-goal', 'rename']
    >>> [o.name for o in apply_script(MapData(), edits).objects]
    ['B']
"""

from __future__ import annotations

import inspect
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mapkit._typing import PathLike
from mapkit.edit import ops
from mapkit.edit.selection import Region
from mapkit.errors import EditError, MapkitError
from mapkit.model import MapData

__all__ = ["OPERATIONS", "Edit", "apply_script", "load_script", "parse_script"]


@dataclass(frozen=True)
class Edit:
    """One edit of a script.

    Attributes:
        op: Operation name (``add-goal``, ``erase``, ...).
        args: Its arguments, keys with ``_``.
        line: Line in the file (YAML only), or ``None``.
        index: 1-based position in the script.
        source: The script's file name.
    """

    op: str
    args: dict[str, Any] = field(default_factory=dict)
    line: int | None = None
    index: int = 1
    source: str = "<script>"

    @property
    def where(self) -> str:
        """``file: edit N (op), line L`` for messages."""
        line = f", line {self.line}" if self.line else ""
        return f"{self.source}: edit {self.index} ({self.op}{line})"


# -- operations --------------------------------------------------------------------------------
# Most operations are the library functions themselves (their keyword names are the CLI's); the
# adapters below only turn a script's lists into the functions' arguments.


def _region(box: Any, polygon: Any) -> Region:
    region = Region.from_spec(box, polygon)
    if region is None:
        raise EditError("give a region: box [x1, y1, x2, y2] or polygon [[x, y], ...]")
    return region


def _remove(
    m: MapData, *, names: str | Sequence[str], type: str | None = None, all: bool = False
) -> MapData:
    return ops.remove(
        m, *([names] if isinstance(names, str) else names), type=type, all_matches=all
    )


def _erase(
    m: MapData, *, box: Any = None, polygon: Any = None, sources: Sequence[str] | None = None
) -> MapData:
    return ops.erase(m, _region(box, polygon), sources=sources)


def _crop(
    m: MapData, *, box: Any = None, polygon: Any = None, keep_objects: bool = False
) -> MapData:
    return ops.crop(m, _region(box, polygon), keep_objects=keep_objects)


def _draw_line(
    m: MapData, *, line: Sequence[float], source: str | None = None, as_points: bool = False
) -> MapData:
    if not isinstance(line, (list, tuple)) or len(line) != 4:
        raise EditError(f"line is [x1, y1, x2, y2], got {line!r}")
    return ops.draw_line(m, *line, source=source, as_points=as_points)


def _merge(
    m: MapData,
    *,
    other: str,
    box: Any = None,
    polygon: Any = None,
    on_clash: str = "keep",
    _base_dir: str = ".",
) -> MapData:
    from mapkit.formats.map import load

    path = other if os.path.isabs(other) else os.path.join(_base_dir, other)
    return ops.merge(m, load(path), region=Region.from_spec(box, polygon), on_clash=on_clash)


#: Operation name -> function ``(map, **args) -> map``.
OPERATIONS: dict[str, Callable[..., MapData]] = {
    "add-goal": ops.add_goal,
    "add-dock": ops.add_dock,
    "add-home": ops.add_home,
    "add-object": ops.add_object,
    "forbid": ops.forbid,
    "remove": _remove,
    "rename": ops.rename,
    "move": ops.move,
    "erase": _erase,
    "draw-line": _draw_line,
    "transform": ops.transform,
    "crop": _crop,
    "merge": _merge,
}


# -- reading -----------------------------------------------------------------------------------


def _yaml_with_lines(text: str) -> Any:
    import yaml

    class Loader(yaml.SafeLoader):  # type: ignore[misc]
        pass

    def mapping(loader: yaml.SafeLoader, node: yaml.MappingNode) -> dict[Any, Any]:
        out: dict[Any, Any] = loader.construct_mapping(node, deep=True)
        out["__line__"] = node.start_mark.line + 1
        return out

    Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, mapping)
    return yaml.load(text, Loader=Loader)


def _strip_lines(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _strip_lines(x) for k, x in v.items() if k != "__line__"}
    if isinstance(v, list):
        return [_strip_lines(x) for x in v]
    return v


def parse_script(text: str, *, source: str = "<script>", yaml: bool | None = None) -> list[Edit]:
    """Read a script's text (YAML, of which JSON is a subset, unless ``yaml=False``).

    Raises:
        EditError: Not a list of edits, an unknown operation, or malformed YAML/JSON.
    """
    if yaml is False:
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as err:
            raise EditError(f"{source}:{err.lineno}: not valid JSON: {err.msg}") from None
    else:
        import yaml as _yaml

        try:
            doc = _yaml_with_lines(text)
        except _yaml.YAMLError as err:
            mark = getattr(err, "problem_mark", None)
            where = f"{source}:{mark.line + 1}" if mark is not None else source
            raise EditError(f"{where}: not valid YAML: {getattr(err, 'problem', err)}") from None
    if isinstance(doc, dict):
        extra = sorted(k for k in doc if k not in ("edits", "__line__"))
        if extra or "edits" not in doc:
            raise EditError(
                f"{source}: a script is a list of edits or a mapping with 'edits:' "
                f"(unexpected keys: {', '.join(map(str, extra)) or 'no edits key'})"
            )
        doc = doc["edits"]
    if not isinstance(doc, list):
        raise EditError(f"{source}: a script is a list of edits, got {type(doc).__name__}")
    edits = []
    for i, item in enumerate(doc, 1):
        line = item.get("__line__") if isinstance(item, dict) else None
        item = _strip_lines(item)
        where = f"{source}: edit {i}" + (f" (line {line})" if line else "")
        if not isinstance(item, dict) or not item:
            raise EditError(
                f"{where}: an edit is a mapping like {{add-goal: {{...}}}} or {{op: add-goal, ...}}"
            )
        if "op" in item:
            op = item.pop("op")
            args = item
        elif len(item) == 1:
            op, args = next(iter(item.items()))
            if args is None:
                args = {}
        else:
            raise EditError(
                f"{where}: name the operation with 'op:' or as the only key, got {sorted(item)}"
            )
        if op not in OPERATIONS:
            raise EditError(f"{where}: unknown operation {op!r}; known: {', '.join(OPERATIONS)}")
        if not isinstance(args, dict):
            if op == "remove" and isinstance(args, (list, str)):
                args = {"names": args}
            else:
                raise EditError(f"{where}: the arguments of {op} must be a mapping, got {args!r}")
        norm = {str(k).replace("-", "_"): v for k, v in args.items()}
        edits.append(Edit(op, norm, line, i, source))
    return edits


def load_script(path: PathLike) -> list[Edit]:
    """Read a script file (``.json`` as JSON, anything else as YAML).

    Raises:
        EditError: See :func:`parse_script`.
        OSError: The file cannot be read.
    """
    p = Path(path)
    text = p.read_text(encoding="utf-8")
    return parse_script(
        text, source=os.fspath(path), yaml=None if p.suffix.lower() != ".json" else False
    )


def _call(edit: Edit, m: MapData, base_dir: str) -> MapData:
    fn = OPERATIONS[edit.op]
    sig = inspect.signature(fn)
    allowed = [p for p in sig.parameters if p not in ("m",) and not p.startswith("_")]
    unknown = [k for k in edit.args if k not in allowed]
    if unknown:
        raise EditError(
            f"{edit.where}: unknown {'argument' if len(unknown) == 1 else 'arguments'} "
            f"{', '.join(unknown)}; {edit.op} takes "
            f"{', '.join(a.replace('_', '-') for a in allowed)}"
        )
    missing = [
        p
        for p in allowed
        if sig.parameters[p].default is inspect.Parameter.empty and p not in edit.args
    ]
    if missing:
        raise EditError(
            f"{edit.where}: missing {'argument' if len(missing) == 1 else 'arguments'} "
            f"{', '.join(a.replace('_', '-') for a in missing)}"
        )
    kwargs = dict(edit.args)
    if "_base_dir" in sig.parameters:
        kwargs["_base_dir"] = base_dir
    try:
        return fn(m, **kwargs)
    except MapkitError as err:
        raise EditError(f"{edit.where}: {err}") from err
    except OSError as err:
        raise EditError(f"{edit.where}: {err.filename}: {err.strerror}") from err
    except (TypeError, ValueError) as err:
        raise EditError(f"{edit.where}: bad argument: {err}") from err


def apply_script(m: MapData, edits: Sequence[Edit], *, base_dir: PathLike = ".") -> MapData:
    """Apply edits in order and return the final map (nothing is written).

    Args:
        m: The map.
        edits: From :func:`load_script` or :func:`parse_script`.
        base_dir: Folder that relative paths in the script (``merge: other``) start from.

    Raises:
        EditError: The first edit refused, named by file, position and line.
    """
    for e in edits:
        m = _call(e, m, os.fspath(base_dir))
    return m
