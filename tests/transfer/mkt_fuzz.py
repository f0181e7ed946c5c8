"""Frame fuzzing for MKT/1: honest frames, mutated by structure (JSON fields set to hostile
values, deep nesting, huge numbers, lone surrogates, wrong types) and by bytes (flips, cuts,
splices, header fields rewritten with or without fixing the CRCs and tags).

Used by ``test_mkt_fuzz.py`` (against the sans-I/O core and a real ``mapkit serve``) and by the
ROS tests (frames published to a real ``mapkit ros serve``). Seeded: a failure names the seed.
"""

from __future__ import annotations

import json
import random
import struct
import zlib
from typing import Any

from mapkit.transfer.protocol import HEADER_SIZE, FrameType, dump_json

#: Honest payloads of every control frame type (what the peers really send).
HONEST: dict[int, dict[str, Any]] = {
    FrameType.HELLO: {
        "versions": [1],
        "nonce": "11" * 32,
        "auth": ["blake2b", "hmac-sha256"],
        "peer": "fuzz",
        "software": "mapkit",
    },
    FrameType.HELLO_ACK: {
        "version": 1,
        "nonce": "22" * 32,
        "auth": "blake2b",
        "peer": "robot",
        "software": "mapkit",
        "max_chunk": 1 << 20,
        "max_size": 1 << 30,
        "features": ["push", "pull", "list", "load"],
    },
    FrameType.AUTH: {"proof": "33" * 32},
    FrameType.AUTH_OK: {"proof": "44" * 32},
    FrameType.REJECT: {"code": 4, "reason": "bad_name", "message": "bad name"},
    FrameType.CANCEL: {"code": 14, "reason": "cancelled", "message": "by the user"},
    FrameType.PING: {"t": 1},
    FrameType.BYE: {},
    FrameType.OFFER: {
        "name": "office.map",
        "size": 40,
        "sha256": "ab" * 32,
        "chunk_size": 16,
        "chunks": 3,
        "kind": "map",
        "md5": "cd" * 16,
        "mtime": 1.5,
        "window": 16,
    },
    FrameType.ACCEPT: {"have": "", "window": 64},
    FrameType.ACK: {"next": 1, "sack": [[2, 3]], "nack": [1]},
    FrameType.DONE: {},
    FrameType.VERIFIED: {
        "name": "office.map",
        "size": 40,
        "sha256": "ab" * 32,
        "md5": "cd" * 16,
        "kind": "map",
    },
    FrameType.GET: {"name": "office.map", "chunk_size": 16, "if_md5": "cd" * 16},
    FrameType.NOT_MODIFIED: {
        "name": "office.map",
        "size": 40,
        "sha256": "ab" * 32,
        "chunk_size": 16,
        "chunks": 3,
        "kind": "map",
        "md5": "cd" * 16,
    },
    FrameType.LIST: {},
    FrameType.LISTING: {
        "maps": [
            {
                "name": "office.map",
                "size": 40,
                "md5": "cd" * 16,
                "sha256": "ab" * 32,
                "mtime": 1.0,
                "kind": "map",
                "active": True,
            }
        ],
        "active": "office.map",
        "active_md5": "cd" * 16,
        "previous": None,
    },
    FrameType.LOAD: {"name": "office.map", "md5": "cd" * 16},
    FrameType.LOADED: {
        "name": "office.map",
        "md5": "cd" * 16,
        "sha256": "ab" * 32,
        "size": 40,
        "loaded_at": 1.0,
        "previous": None,
    },
}


def hostile_value(rng: random.Random) -> Any:
    """A JSON value chosen to break a careless decoder or handler."""
    k = rng.randrange(16)
    if k == 0:
        return _nested(rng.choice([20, 100, 400]), rng)  # deeper ones: _RAW_TEXTS
    if k == 1:
        return -rng.randrange(1 << 70)
    if k == 2:
        return rng.choice([0, -1, 1 << 32, 1 << 63, (1 << 64) + 1, 10**19])
    if k == 3:
        return rng.choice([1e308, -1e308, 5e-324, 0.5, -0.0])
    if k == 4:
        return rng.choice(
            [
                "",
                "\ud800",
                "a\x00b",
                "../../etc/passwd.map",
                "CON.map",
                "é" * 150,
                "x" * rng.randrange(1, 5000),
                "\u202e.map",
                ".hidden.map",
                "-x.map",
            ]
        )
    if k == 5:
        return rng.choice([True, False, None])
    if k == 6:
        return [hostile_value(rng) for _ in range(rng.randrange(4))]
    if k == 7:
        return {str(rng.randrange(100)): hostile_value(rng) for _ in range(rng.randrange(3))}
    if k == 8:
        return [
            [rng.randrange(-5, 1 << 33), rng.randrange(-5, 1 << 33)]
            for _ in range(rng.randrange(40))
        ]
    if k == 9:
        n = rng.choice([0, 31, 32, 64, 65])
        return "".join(rng.choice("0123456789abcdefABCDEF") for _ in range(n))
    if k == 10:
        return rng.randrange(-3, 70)
    if k == 11:
        return rng.choice(["map", "2d", "file", "MAP", "", "none", "blake2b", "hmac-sha256"])
    if k == 12:
        return [rng.choice(["push", 1, None, "blake2b"]) for _ in range(rng.randrange(5))]
    if k == 13:
        return "=" * rng.randrange(8) + "AAAA" * rng.randrange(4)  # base64-ish
    return rng.randrange(1 << 20)


def _nested(depth: int, rng: random.Random) -> Any:
    v: Any = rng.choice([1, "x", None])
    for _ in range(depth):
        v = [v] if rng.random() < 0.5 else {"k": v}
    return v


_RAW_TEXTS = [
    lambda rng: b"[" * rng.choice([17, 1000, 100_000]) + b"]" * rng.randrange(3),
    lambda rng: b'{"a":' * rng.choice([17, 1000, 100_000]),
    lambda rng: b'{"size":' + b"9" * rng.choice([21, 4301, 50_000]) + b"}",
    lambda rng: b'{"mtime":NaN,"size":Infinity}',
    lambda rng: b'{"name":"\\ud800.map"}',
    lambda rng: b"\xff\xfe{}",
    lambda rng: b"[]",
    lambda rng: b'"just a string"',
    lambda rng: b"{" + b'"a":1,' * rng.randrange(1000) + b"}",
    lambda rng: b'{"name":"' + b'\\"' * rng.randrange(1, 20000),
    lambda rng: bytes(rng.randrange(256) for _ in range(rng.randrange(64))),
    lambda rng: b'{"x":"' + b"[" * 50_000 + b'"}',
]


def mutate_payload(ftype: int, rng: random.Random) -> bytes:
    """A payload for ``ftype``: the honest one with hostile fields, or hostile JSON text."""
    if ftype == FrameType.DATA:
        return bytes(rng.randrange(256) for _ in range(rng.choice([0, 1, 15, 16, 17, 100])))
    if rng.random() < 0.25:
        return _RAW_TEXTS[rng.randrange(len(_RAW_TEXTS))](rng)
    d = json.loads(json.dumps(HONEST.get(ftype, {})))
    for _ in range(rng.randrange(1, 4)):
        keys = list(d) or ["x"]
        op = rng.randrange(4)
        key = rng.choice(keys)
        if op == 0:
            d[key] = hostile_value(rng)
        elif op == 1:
            d.pop(key, None)
        elif op == 2:
            extra = rng.choice(["extra", "rollback", "skip", "if_sha256", "chunks", "window"])
            d[extra] = hostile_value(rng)
        else:
            d[key] = _nested(rng.choice([2, 15, 16, 17, 40]), rng)
    try:
        return dump_json(d)
    except (ValueError, UnicodeEncodeError):  # a lone surrogate: written escaped instead
        return json.dumps(d).encode("ascii")


def mutate_bytes(frame: bytes, rng: random.Random) -> bytes:
    """Byte-level damage to an encoded frame (CRCs sometimes fixed so it gets past them)."""
    b = bytearray(frame)
    k = rng.randrange(7)
    if k == 0 and b:
        for _ in range(rng.randrange(1, 4)):
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
    elif k == 1:
        b = b[: rng.randrange(len(b) + 1)]
    elif k == 2:
        pos = rng.randrange(len(b) + 1)
        b[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 40)))
    elif k == 3 and len(b) >= HEADER_SIZE:  # rewrite a header field, then fix the head CRC
        field = rng.choice([(4, "B"), (5, "B"), (6, "H"), (16, "I"), (20, "I"), (24, "I")])
        off, fmt = field
        value = rng.randrange(1 << (8 * struct.calcsize(fmt)))
        struct.pack_into(">" + fmt, b, off, value)
        struct.pack_into(">I", b, 32, zlib.crc32(bytes(b[:32])))
    elif k == 4:
        b = b + b  # two frames back to back
    elif k == 5:
        b = b"MKT1" + b
    return bytes(b)


def frame_types(rng: random.Random) -> int:
    """A frame type: mostly known ones, sometimes reserved or unknown."""
    if rng.random() < 0.1:
        return rng.choice([0, 10, 15, 22, 31, 39, 200, 255])
    return int(rng.choice([*list(HONEST), FrameType.DATA]))
