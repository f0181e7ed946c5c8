"""A bounded JSON decoder for protocol messages: depth, size, numbers, strings and field types.

Every control payload of MKT/1 (and the ROS announcement) comes from a peer that may be
hostile, possibly before it has authenticated. Python's :func:`json.loads` recurses once per
nesting level (a value nested 100,000 deep raises :class:`RecursionError`), parses integers of
any length (quadratic time past Python's digit limit, or a :class:`ValueError` at it) and
accepts ``NaN``, ``Infinity`` and lone UTF-16 surrogates. :func:`decode_object` puts limits in
front of it and behind it:

* **size**: at most ``max_size`` bytes (1 MiB for control frames);
* **depth**: checked before parsing, in linear time, with strings skipped: at most
  ``max_depth`` nested arrays/objects (MKT/1's deepest message, a LISTING, nests 3), see
  :func:`deeper_than`;
* **numbers**: integers of at most 20 digits (every protocol integer fits in 64 bits), finite
  floats of at most 40 characters; ``NaN``/``Infinity`` are refused;
* **strings**: valid Unicode (no lone surrogates), so a name or message can always be encoded
  as UTF-8 for a log or a terminal;
* **types**: :func:`check_fields` checks the known fields of a message against a
  :data:`SCHEMAS` entry (unknown fields are ignored, as the spec requires).

Everything it refuses raises :class:`WireJSONError` (a :class:`ValueError`); the protocol core
turns it into a ``protocol`` error for the peer. This module imports nothing from mapkit, so
the sans-I/O core and the ROS binding can both use it.
"""

from __future__ import annotations

import itertools
import json
import re
from collections.abc import Mapping
from typing import Any

__all__ = [
    "MAX_DEPTH",
    "MAX_INT_DIGITS",
    "MAX_SIZE",
    "SCHEMAS",
    "ListOf",
    "WireJSONError",
    "check_fields",
    "decode_object",
    "deeper_than",
    "json_depth",
]

MAX_SIZE = 1024 * 1024
MAX_DEPTH = 16
MAX_INT_DIGITS = 20
MAX_FLOAT_CHARS = 40

# a JSON string with its escapes; an unterminated one runs to the end of the text, so that a
# scan never restarts inside a string (linear time whatever the quotes and backslashes)
_STRING = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"?', re.DOTALL)
_DELTA = [0] * 256
for _c in b"[{":
    _DELTA[_c] = 1
for _c in b"]}":
    _DELTA[_c] = -1
_KEEP = bytes(range(256)).translate(None, b"[]{}")  # every byte but brackets: deleted


class WireJSONError(ValueError):
    """A payload the bounded decoder refuses (the message says why)."""


def json_depth(data: bytes) -> int:
    """The deepest nesting of arrays and objects in JSON text (brackets inside strings skipped).

    Linear time and constant stack, whatever the input (also for text that is not JSON: then
    it is an upper bound of what a JSON parser would reach before failing).

    Examples:
        >>> json_depth(b'{"a":[1,{"b":"[[["}]}')
        3
        >>> json_depth(b"[" * 100000)
        100000
    """
    if b"[" not in data and b"{" not in data:
        return 0
    structure = _STRING.sub(b"", data).translate(None, _KEEP)
    return max(itertools.accumulate(map(_DELTA.__getitem__, structure)), default=0)


# brackets as ( and ): one bytes.replace of "()" removes exactly one level (it does not rescan)
_PARENS = bytes.maketrans(b"[{]}", b"(())")
_SURROGATE_ESCAPE = re.compile(rb"\\u[dD][89a-fA-F]")


def deeper_than(data: bytes, limit: int) -> bool:
    """True when JSON text nests arrays/objects more than ``limit`` deep, or its brackets (outside
    strings) do not balance. Linear, in C: strings are cut out, then at most ``limit`` rounds
    remove the innermost pairs.

    Examples:
        >>> deeper_than(b'{"a":[1,{"b":"[[["}]}', 3), deeper_than(b'{"a":[1,{"b":2}]}', 2)
        (False, True)
        >>> deeper_than(b"[" * 100000, 16)
        True
    """
    if data.count(b"[") + data.count(b"{") <= limit:
        return False  # not enough openers to nest deeper (closers in excess fail to parse)
    structure = _STRING.sub(b"", data).translate(_PARENS, _KEEP)
    if b"(" * (limit + 1) in structure:
        return True  # a run of openers deeper than the limit
    for _ in range(limit):
        before = len(structure)
        structure = structure.replace(b"()", b"")
        if not structure:
            return False
        if len(structure) == before:
            return True  # nothing left to pair: unbalanced
    return bool(structure)


def _parse_int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise WireJSONError(
            f"an integer of {len(text.lstrip('-'))} digits (at most {MAX_INT_DIGITS})"
        )
    return int(text)


def _parse_float(text: str) -> float:
    if len(text) > MAX_FLOAT_CHARS:
        raise WireJSONError(f"a number of {len(text)} characters (at most {MAX_FLOAT_CHARS})")
    value = float(text)
    if value in (float("inf"), float("-inf")):
        raise WireJSONError(f"the number {text} is out of range")
    return value


def _no_constant(text: str) -> Any:
    raise WireJSONError(f"{text} is not a JSON number")


def _check_strings(obj: Any) -> None:
    """Refuse strings that are not valid Unicode (lone surrogates); depth is already bounded."""
    if isinstance(obj, str):
        try:
            obj.encode("utf-8")
        except UnicodeEncodeError as err:
            raise WireJSONError("a string with a lone UTF-16 surrogate") from err
    elif isinstance(obj, dict):
        for k, v in obj.items():
            _check_strings(k)
            _check_strings(v)
    elif isinstance(obj, list):
        for v in obj:
            _check_strings(v)


def decode_object(
    payload: bytes | bytearray | memoryview | str,
    *,
    max_size: int = MAX_SIZE,
    max_depth: int = MAX_DEPTH,
) -> dict[str, Any]:
    """Decode a UTF-8 JSON object within the limits above (an empty payload is ``{}``).

    Raises:
        WireJSONError: When the payload is too large, too deep, not UTF-8 JSON, not an object,
            or holds a number or string out of bounds.

    Examples:
        >>> decode_object(b'{"name":"a.map","size":3}')
        {'name': 'a.map', 'size': 3}
        >>> decode_object(b"[" * 100000)
        Traceback (most recent call last):
        ...
        mapkit.transfer.wirejson.WireJSONError: nested deeper than 16 levels
    """
    data = payload.encode("utf-8", "surrogatepass") if isinstance(payload, str) else bytes(payload)
    if len(data) > max_size:
        raise WireJSONError(f"{len(data)} bytes (at most {max_size})")
    if not data:
        return {}
    if deeper_than(data, max_depth):
        raise WireJSONError(f"nested deeper than {max_depth} levels")
    try:
        text = data.decode("utf-8")
        obj = json.loads(
            text, parse_int=_parse_int, parse_float=_parse_float, parse_constant=_no_constant
        )
    except WireJSONError:
        raise
    except (UnicodeDecodeError, ValueError) as err:
        raise WireJSONError(f"not UTF-8 JSON: {err}") from err
    except RecursionError as err:  # pragma: no cover - the depth check comes first
        raise WireJSONError("nested too deep") from err
    if not isinstance(obj, dict):
        raise WireJSONError("not a JSON object")
    if _SURROGATE_ESCAPE.search(data):  # raw UTF-8 cannot hold one; only a \u escape can
        _check_strings(obj)
    return obj


# -- field types --------------------------------------------------------------------------------

# A field spec is a tuple of alternatives, each a kind name ("str", "int" (not a boolean),
# "num" (int or float, not a boolean), "bool", "null", "any"), a dict (an object whose own
# fields are checked) or a ListOf (an array whose items all match its spec).


class ListOf:
    """A field spec alternative: an array whose items all match ``item`` (a spec tuple)."""

    __slots__ = ("item",)

    def __init__(self, item: tuple[Any, ...]) -> None:
        self.item = item


Spec = tuple[Any, ...]

_KINDS: dict[str, Any] = {
    "str": lambda v: isinstance(v, str),
    "int": lambda v: isinstance(v, int) and not isinstance(v, bool),
    "num": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
    "bool": lambda v: isinstance(v, bool),
    "null": lambda v: v is None,
    "any": lambda v: True,
}
_NAMES = {
    "str": "a string",
    "int": "an integer",
    "num": "a number",
    "bool": "true or false",
    "null": "null",
    "any": "anything",
}

_STR: Spec = ("str",)
_INT: Spec = ("int",)
_OPT_STR: Spec = ("str", "null")
_RANGE: Spec = (ListOf((ListOf(_INT),)),)  # [[a, b), ...]
_OFFER: dict[str, Spec] = {
    "name": _STR,
    "size": _INT,
    "sha256": _STR,
    "chunk_size": _INT,
    "chunks": _INT,
    "kind": _STR,
    "md5": _OPT_STR,
    "mtime": ("num", "null"),
    "window": _INT,
}
_REJECT: dict[str, Spec] = {"code": _INT, "reason": _STR, "message": _STR}
_LOADED: dict[str, Spec] = {
    "name": _STR,
    "md5": _STR,
    "sha256": _STR,
    "size": _INT,
    "loaded_at": ("num",),
    "map_server": ("int", "null"),
    "previous": ({"name": _OPT_STR, "md5": _OPT_STR, "sha256": _OPT_STR}, "null"),
}

#: Known fields of each control frame, by frame type number (see the MKT/1 spec, section 3).
SCHEMAS: dict[int, dict[str, Spec]] = {
    1: {
        "versions": (ListOf(("any",)),),
        "nonce": _STR,
        "auth": ("str", ListOf(_STR)),
        "peer": _STR,
        "software": _STR,
    },  # HELLO
    2: {
        "version": ("any",),
        "nonce": _STR,
        "auth": _STR,
        "peer": _STR,
        "software": _STR,
        "max_chunk": _INT,
        "max_size": _INT,
        "features": (ListOf(_STR),),
    },  # HELLO_ACK
    3: {"proof": _STR},  # AUTH
    4: {"proof": _STR},  # AUTH_OK
    5: _REJECT,
    6: _REJECT,  # CANCEL
    16: _OFFER,
    17: {"have": _OPT_STR, "window": _INT, "skip": ("bool",)},  # ACCEPT
    19: {"next": _INT, "sack": _RANGE, "nack": (ListOf(_INT),)},  # ACK
    21: {"name": _STR, "size": _INT, "sha256": _STR, "md5": _OPT_STR, "kind": _STR},  # VERIFIED
    32: {"name": _STR, "chunk_size": _INT, "if_md5": _OPT_STR, "if_sha256": _OPT_STR},  # GET
    33: _OFFER,  # NOT_MODIFIED
    35: {
        "maps": (
            ListOf(
                (
                    {
                        "name": _STR,
                        "size": _INT,
                        "md5": _STR,
                        "sha256": _STR,
                        "mtime": ("num",),
                        "kind": _STR,
                        "active": ("bool",),
                    },
                )
            ),
        ),
        "active": _OPT_STR,
        "active_md5": _OPT_STR,
        "previous": _OPT_STR,
    },  # LISTING
    36: {"name": _OPT_STR, "md5": _OPT_STR, "rollback": ("bool",)},  # LOAD
    37: _LOADED,
    38: _LOADED,  # ANNOUNCE
}


def _fail(value: Any, spec: Spec) -> str | None:
    """Where and why ``value`` does not match ``spec`` (a path suffix and a reason), or None."""
    for alt in spec:
        if isinstance(alt, str):
            if _KINDS[alt](value):
                return None
        elif isinstance(alt, dict):
            if isinstance(value, dict):
                return _fields_fail(value, alt)
        elif isinstance(value, list):  # ListOf
            for i, v in enumerate(value):
                why = _fail(v, alt.item)
                if why is not None:
                    return f"[{i}]{why}"
            return None
    return f" must be {_describe(spec)}, not {type(value).__name__}"


def _fields_fail(obj: Mapping[str, Any], schema: Mapping[str, Spec]) -> str | None:
    for key, spec in schema.items():
        if key in obj:
            why = _fail(obj[key], spec)
            if why is not None:
                return f".{key}{why}"
    return None


def _describe(spec: Spec) -> str:
    return " or ".join(
        "an object" if isinstance(a, dict) else "a list" if isinstance(a, ListOf) else _NAMES[a]
        for a in spec
    )


def check_fields(obj: Mapping[str, Any], schema: Mapping[str, Spec], what: str = "message") -> None:
    """Check the types of the known fields of ``obj`` (absent fields and unknown ones pass).

    Raises:
        WireJSONError: Naming the first field of the wrong type, as a path.

    Examples:
        >>> check_fields({"size": "3"}, SCHEMAS[16], "OFFER")
        Traceback (most recent call last):
        ...
        mapkit.transfer.wirejson.WireJSONError: OFFER.size must be an integer, not str
        >>> check_fields({"sack": [[0, 2], [5, None]]}, SCHEMAS[19], "ACK")
        Traceback (most recent call last):
        ...
        mapkit.transfer.wirejson.WireJSONError: ACK.sack[1][1] must be an integer, not NoneType
    """
    why = _fields_fail(obj, schema)
    if why is not None:
        raise WireJSONError(what + why)
