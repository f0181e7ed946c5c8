"""Fuzzing import-ros: mutated map YAMLs, PGMs and PNGs give a map or mapkit's own error.

A seeded mutation loop (reproducible: the seed and the iteration are in the failure message),
bounded in time. Anything but a :class:`~mapkit.errors.MapkitError` fails.
"""

from __future__ import annotations

import os
import random
import re
import time
from pathlib import Path

import numpy as np
import pytest

from mapkit.errors import MapkitError
from mapkit.raster import OccupancyGrid
from mapkit.raster.import_ros import import_ros
from mapkit.raster.ros import write_ros_map

BUDGET_S = float(os.environ.get("MAPKIT_FUZZ_S", "3"))  # per target
TOKENS = [
    b"nan",
    b".nan",
    b".inf",
    b"-.inf",
    b"1e309",
    b"1e308",
    b"-0",
    b"09",
    b"0x7fffffff",
    b"9" * 5000,
    b"&a",
    b"*a",
    b"!!binary",
    b"[",
    b"]",
    b"{",
    b"}",
    b":",
    b"- ",
    b"\0",
    b"\xff",
    b"#",
    b"\n",
    b"\t",
    b"'",
    b'"',
    b"~",
    b"65535",
    b"0",
    b"4294967296",
    b"40000",
    b"-1",
    b"P5",
    b"P2",
    b"IHDR",
    b"IEND",
    b"\x00\x00\x9c\x40",
]


VALUE = re.compile(rb"(?<=: )[^\n]*|(?<=\[)[^,\]]*|(?<=, )[^,\]]*")


def mutate(data: bytes, rng: random.Random) -> bytes:
    buf = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(7)
        # Headers hold most of the structure: aim there half of the time.
        at = (
            rng.randrange(min(len(buf), 40) + 1)
            if rng.random() < 0.5
            else rng.randrange(len(buf) + 1)
        )
        if op == 6:  # a YAML value (or a list element) replaced by a hostile one
            spans = [m.span() for m in VALUE.finditer(bytes(buf)) if m.start() < 4000]
            if spans:
                a, b = rng.choice(spans)
                buf[a:b] = rng.choice(TOKENS)
            continue
        if op == 0 and buf:  # flip a byte
            buf[min(at, len(buf) - 1)] = rng.randrange(256)
        elif op == 1:  # insert a token
            buf[at:at] = rng.choice(TOKENS)
        elif op == 2:  # delete a span
            del buf[at : at + rng.randint(1, 16)]
        elif op == 3:  # duplicate a span
            buf[at:at] = buf[at : at + rng.randint(1, 64)]
        elif op == 4:  # truncate
            del buf[at:]
        else:  # replace a number by another
            buf[at : at + rng.randint(1, 4)] = str(
                rng.choice([0, 1, 255, 256, 65536, 2**40, -7])
            ).encode()
    return bytes(buf)


@pytest.fixture(scope="module")
def seeds(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    d = tmp_path_factory.mktemp("seed")
    rng = np.random.default_rng(5)
    g = OccupancyGrid(
        rng.choice(np.array([-1, 0, 100, 37], dtype=np.int8), (12, 9)), 0.05, (-1.0, 2.0)
    )
    out: dict[str, bytes] = {}
    files = write_ros_map(g.with_data(np.where(g.data == 37, 0, g.data)), d / "t.yaml")
    out["t.yaml"], out["t.pgm"] = files.yaml.read_bytes(), files.image.read_bytes()
    files = write_ros_map(g, d / "s.yaml", mode="scale")
    out["s.yaml"], out["s.png"] = files.yaml.read_bytes(), files.image.read_bytes()
    out["a.pgm"] = b"P2\n# ascii\n3 2\n255\n0 254 205\n0 0 254\n"
    return out


def fuzz(tmp_path: Path, seeds: dict[str, bytes], seed: int, target: str) -> int:
    rng = random.Random(seed)
    deadline = time.monotonic() + BUDGET_S
    runs = 0
    while time.monotonic() < deadline:
        runs += 1
        case = tmp_path / f"c{runs % 4}"
        case.mkdir(exist_ok=True)
        for name, data in seeds.items():
            (case / name).write_bytes(mutate(data, rng) if name == target else data)
        yaml_name = "s.yaml" if target.startswith("s.") else "t.yaml"
        if target == "a.pgm":
            (case / yaml_name).write_bytes(seeds["t.yaml"].replace(b"t.pgm", b"a.pgm"))
        flavor = rng.choice(["ros1", "nav2"])
        try:
            import_ros(
                case / yaml_name,
                flavor=flavor,  # type: ignore[arg-type]
                band_rows=rng.choice([None, 1, 3]),
            )
        except MapkitError:
            pass
        except Exception as err:  # pragma: no cover - the failure being looked for
            pytest.fail(f"seed {seed} run {runs} ({target}, {flavor}): {type(err).__name__}: {err}")
    return runs


@pytest.mark.parametrize("target", ["t.yaml", "s.yaml", "t.pgm", "s.png", "a.pgm"])
def test_mutated_inputs_give_a_map_or_mapkits_error(
    tmp_path: Path, seeds: dict[str, bytes], target: str
) -> None:
    runs = fuzz(tmp_path, seeds, seed=sum(target.encode()), target=target)
    assert runs > 20  # the budget bought real work
