"""6xx: info sections: type declarations, their ArgDesc parameters, and CairnInfo: values."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

from mapkit.diagnostics import IssueCode as C
from mapkit.formats._numbers import aria_double, aria_int
from mapkit.model import MapObject
from mapkit.validate._context import Context, key_values, rule, unquote

__all__ = ["ARG_TYPES", "ArgDesc", "arg_descs", "fits"]

ARG_TYPES = ("int", "double", "string", "bool")
_BOOL = ("true", "false", "1", "0")


def fits(value: str, arg_type: str) -> bool:
    """Whether a value can be read as an ArgDesc type (``int``, ``double``, ``bool``, ``string``).

    Numbers are read as ARIA reads them (``strtol``/``strtod`` on the whole value, any length in
    linear time).

    Examples:
        >>> fits("12", "int"), fits("1.5", "int"), fits("inf", "double"), fits("yes", "bool")
        (True, False, True, False)
    """
    t = arg_type.lower()
    if t == "int":
        return aria_int(value) is not None
    if t == "double":
        return aria_double(value) is not None
    if t == "bool":
        return value.lower() in _BOOL
    return True


def _number(value: str) -> float | None:
    return aria_double(value)


@dataclass(frozen=True)
class ArgDesc:
    """One ``ArgDesc`` line: a parameter of a type (or a task)."""

    name: str
    parent: str
    type: str
    params: dict[str, str]
    section: str
    index: int


def arg_descs(ctx: Context, section: str = "MapInfo") -> dict[str, list[ArgDesc]]:
    """ArgDesc lines of a section by parent (type or task) name, in order."""
    out: dict[str, list[ArgDesc]] = defaultdict(list)
    for i, line in enumerate(ctx.map.info.get(section, ())):
        if line and line[0] == "ArgDesc":
            kv = key_values(line[1:])
            out[kv.get("Parent", "")].append(
                ArgDesc(
                    kv.get("Name", ""), kv.get("Parent", ""), kv.get("Type", ""), kv, section, i
                )
            )
    return dict(out)


def _is_parent_line(section: str, line: tuple[str, ...]) -> bool:
    if section == "MapInfo":
        return bool(line) and line[0].endswith("Type") and line[0] != "FeedbackType"
    return bool(line) and line[0] != "ArgDesc" and "Name" in key_values(line[1:])


@rule(C.TYPE_WITHOUT_NAME, C.TYPE_DECLARED_TWICE)
def declarations(ctx: Context) -> None:
    """``MapInfo:`` type lines: each names a type, once."""
    first: dict[str, int] = {}
    for i, line in enumerate(ctx.map.info.get("MapInfo", ())):
        if not _is_parent_line("MapInfo", line):
            continue
        kv = key_values(line[1:])
        lineno = ctx.info_line("MapInfo", i)
        if not kv.get("Name"):
            ctx.add(
                C.TYPE_WITHOUT_NAME,
                f"MapInfo: {line[0]} without Name=: objects cannot use this type",
                line=lineno,
            )
            continue
        name = kv["Name"]
        if name in first:
            at = ctx.info_line("MapInfo", first[name])
            ctx.add(
                C.TYPE_DECLARED_TWICE,
                f"MapInfo: {line[0]} Name={name} declared again"
                + (f" (first on line {at})" if at else "")
                + ": ARIA's tools use the first declaration",
                line=lineno,
                object=name,
            )
        else:
            first[name] = i


@rule(C.ARGDESC_PARENT_MISMATCH, C.ARGDESC_BAD_TYPE, C.ARGDESC_BAD_VALUE)
def argdescs(ctx: Context) -> None:
    """ArgDesc lines: under their parent, with a known Type= and values that fit it."""
    for section in ("MapInfo", "TaskInfo", "SchedTaskInfo", "MacroInfo"):
        parent: str | None = None
        for i, line in enumerate(ctx.map.info.get(section, ())):
            if not line:
                continue
            if line[0] != "ArgDesc":
                parent = (
                    key_values(line[1:]).get("Name") if _is_parent_line(section, line) else None
                )
                continue
            _check_argdesc(ctx, section, i, key_values(line[1:]), parent)


def _check_argdesc(
    ctx: Context, section: str, i: int, kv: dict[str, str], parent: str | None
) -> None:
    lineno = ctx.info_line(section, i)
    name, ptype = kv.get("Name"), kv.get("Type")
    label = f"{section}: ArgDesc {name!r}" if name else f"{section}: ArgDesc"
    if kv.get("Parent") != parent:
        where = f"under {parent!r}" if parent else "not under a type or task line"
        ctx.add(
            C.ARGDESC_PARENT_MISMATCH,
            f"{label} has Parent={kv.get('Parent', '')!r} but is {where}: ARIA attaches it "
            "to the line above, so the parameter ends up on the wrong type",
            line=lineno,
            object=name,
        )
    if not name or ptype is None or ptype.lower() not in ARG_TYPES:
        why = "no Name=" if not name else f"Type={ptype!r}" if ptype is not None else "no Type="
        ctx.add(
            C.ARGDESC_BAD_TYPE,
            f"{label} has {why}: expected Name= and Type= one of {', '.join(ARG_TYPES)}",
            line=lineno,
            object=name,
        )
        return
    bad = [
        f"{k}={kv[k]!r}"
        for k in ("Value", "Min", "Max")
        if kv.get(k) not in (None, "") and not fits(kv[k], ptype)
    ]
    if bad:
        ctx.add(
            C.ARGDESC_BAD_VALUE,
            f"{label} of Type={ptype} has {', '.join(bad)}",
            line=lineno,
            object=name,
        )
        return
    if ptype.lower() in ("int", "double") and kv.get("Value"):
        v = _number(kv["Value"])
        lo = _number(kv["Min"]) if kv.get("Min") else None
        hi = _number(kv["Max"]) if kv.get("Max") else None
        if v is not None and ((lo is not None and v < lo) or (hi is not None and v > hi)):
            ctx.add(
                C.ARGDESC_BAD_VALUE,
                f"{label}: Value={kv['Value']} is outside Min={kv.get('Min', '-inf')} .. "
                f"Max={kv.get('Max', 'inf')}",
                line=lineno,
                object=name,
            )


def _find(ctx: Context, name: str) -> MapObject | None:
    low = name.lower()
    for o in (*ctx.map.objects, *ctx.map.child_objects):
        if o.name.lower() == low:
            return o
    return None


@rule(C.PARAMS_UNKNOWN_OBJECT, C.PARAMS_COUNT_MISMATCH, C.PARAMS_BAD_VALUE, C.GROUP_MEMBER_MISMATCH)
def cairn_info(ctx: Context) -> None:
    """``CairnInfo: Params`` and ``GroupMember`` lines against objects and their types' ArgDescs."""
    lines = ctx.map.info.get("CairnInfo", ())
    if not lines:
        return
    args = arg_descs(ctx)
    declared = ctx.declared()
    for i, line in enumerate(lines):
        if len(line) < 2:
            continue
        lineno = ctx.info_line("CairnInfo", i)
        name = unquote(line[1])
        if line[0] == "Params":
            obj = _find(ctx, name)
            if obj is None:
                ctx.add(
                    C.PARAMS_UNKNOWN_OBJECT,
                    f"CairnInfo: Params for {name!r}, but the map has no object of that name: "
                    "ARIA keeps the values and uses them for nothing",
                    line=lineno,
                    object=name,
                )
                continue
            descs = args.get(obj.type) or args.get(obj.base_type) or []
            values = [unquote(t) for t in line[2:]]
            if len(values) != len(descs):
                ctx.add(
                    C.PARAMS_COUNT_MISMATCH,
                    f"CairnInfo: Params {name!r} has {len(values)} value"
                    f"{'s' if len(values) != 1 else ''} but type {obj.type!r} has "
                    f"{len(descs)} ArgDesc line{'s' if len(descs) != 1 else ''}: values are "
                    "matched by position, so they land on the wrong parameters",
                    line=lineno,
                    object=name,
                )
                continue
            bad = [
                f"{d.name}={v!r} (Type={d.type})"
                for d, v in zip(descs, values, strict=True)
                if d.type and not fits(v, d.type) and not (v == "" and d.type.lower() != "bool")
            ]
            if bad:
                ctx.add(
                    C.PARAMS_BAD_VALUE,
                    f"CairnInfo: Params {name!r}: {', '.join(bad)} do not fit their types",
                    line=lineno,
                    object=name,
                )
        elif line[0] == "GroupMember" and len(line) >= 5:
            child_type, group_type, arg = (unquote(t) for t in line[2:5])
            problems = []
            obj = _find(ctx, name)
            if obj is None:
                problems.append(f"no object named {name!r}")
            elif obj.type != child_type:
                problems.append(f"{name!r} is a {obj.type}, not a {child_type}")
            if declared.get(group_type) != "CairnGroupType":
                problems.append(f"{group_type!r} is not a declared CairnGroupType")
            elif arg not in {d.name for d in args.get(group_type, [])}:
                problems.append(f"{group_type} has no ArgDesc {arg!r}")
            if problems:
                ctx.add(
                    C.GROUP_MEMBER_MISMATCH,
                    f"CairnInfo: GroupMember {name!r}: " + "; ".join(problems),
                    line=lineno,
                    object=name,
                )
