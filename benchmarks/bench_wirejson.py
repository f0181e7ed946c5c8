"""Benchmark: the bounded JSON decoder of MKT/1 against plain ``json.loads``, same run.

    .venv/bin/python benchmarks/bench_wirejson.py

For honest payloads (an OFFER, an ACK, a LISTING of 1,000 maps) it prints the time per decode
of ``json.loads`` (the baseline) and of :func:`mapkit.transfer.protocol.parse_json` (depth
scan, number and string limits, field types) and their ratio; for hostile 1 MiB payloads it
prints how long the refusal takes (``json.loads`` either raises RecursionError or parses them).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import contextlib

from _timing import best

from mapkit.transfer.protocol import FrameType, ProtocolError, parse_json
from mapkit.transfer.wirejson import SCHEMAS


def _refuse(data: bytes, ftype: FrameType) -> None:
    from mapkit.transfer.protocol import Frame

    with contextlib.suppress(ProtocolError):
        Frame(ftype, 1, 0, data).json()


def main() -> None:
    offer = json.dumps(
        {
            "name": "office.map",
            "size": 614400,
            "sha256": "ab" * 32,
            "chunk_size": 262144,
            "chunks": 3,
            "kind": "map",
            "md5": "cd" * 16,
            "mtime": 1795249871.148,
            "window": 16,
        }
    ).encode()
    ack = json.dumps({"next": 120, "sack": [[i * 3, i * 3 + 2] for i in range(41, 73)]}).encode()
    listing = json.dumps(
        {
            "maps": [
                {
                    "name": f"map{i}.map",
                    "size": 1000 + i,
                    "md5": "cd" * 16,
                    "sha256": "ab" * 32,
                    "mtime": 1.5,
                    "kind": "map",
                    "active": i == 3,
                }
                for i in range(1000)
            ],
            "active": "map3.map",
            "active_md5": "cd" * 16,
            "previous": None,
        }
    ).encode()
    print(f"{'payload':<24}{'json.loads':>14}{'bounded':>14}{'ratio':>9}")
    cases = (
        ("OFFER", offer, FrameType.OFFER),
        ("ACK, 32 ranges", ack, FrameType.ACK),
        ("LISTING, 1000 maps", listing, FrameType.LISTING),
    )
    for name, data, ftype in cases:
        n = 2000 if len(data) < 10_000 else 20
        base = best(lambda d=data, n=n: [json.loads(d) for _ in range(n)], 5) / n
        schema = SCHEMAS[ftype]
        ours = best(lambda d=data, n=n, s=schema: [parse_json(d, "x", s) for _ in range(n)], 5) / n
        print(f"{name:<24}{base * 1e6:>11.1f} us{ours * 1e6:>11.1f} us{ours / base:>8.2f}x")
    hello = b'{"a":' * 3200  # 16 KiB: the most a HELLO may hold
    t = best(lambda: _refuse(hello, FrameType.HELLO), 5)
    print(f"hostile HELLO (16 KiB, the handshake's limit), time to refuse: {t * 1e3:.2f} ms")
    print("hostile, 1 MiB (after authentication), time to refuse:")
    for name, data in (
        ("[ x 1 MiB", b"[" * (1 << 20)),
        ('{"a": x 1 MiB', b'{"a":' * (1 << 18)),
        ("string of [ x 1 MiB", b'{"s":"' + b"[" * (1 << 20) + b'"}'),
        ('\\" x 1 MiB unterminated', b'{"s":"' + b'\\"' * (1 << 19)),
    ):
        data = data[: 1 << 20]

        def refuse(d: bytes = data) -> None:
            with contextlib.suppress(ProtocolError):
                parse_json(d, "x")

        print(f"  {name:<28}{best(refuse, 3) * 1e3:>8.1f} ms")


if __name__ == "__main__":
    main()
