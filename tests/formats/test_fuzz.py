"""A seeded mutation fuzzer over the real and bundled .map and .2d samples.

Every mutated file must either load or fail with mapkit's own error (a ``MapkitError``); what
loads must write, read back and validate without a foreign exception. Inputs are excerpts of the
samples (the header and some rows/records) so that thousands of cases run in seconds; the loop
is seeded (reproducible) and bounded by a case count and a time budget. A failing case is saved
beside the test's temporary folder and named in the failure.
"""

from __future__ import annotations

import contextlib
import random
import time
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

import mapkit
from mapkit import samples
from mapkit.diagnostics import IssueCode
from mapkit.errors import MapkitError
from mapkit.formats.laser2d import dumps_log, loads_log, recover_log
from mapkit.validate import validate
from tests.conftest import SHARED

CASES_PER_SEED = 300
TIME_BUDGET_S = 12.0  # per seed set; the case count is the normal bound

# Values that have broken readers: huge digit runs, C-only and Python-only number syntax, quotes,
# control bytes, invalid UTF-8, a line longer than ARIA's 12,000-byte buffer.
NASTY: list[bytes] = [
    b"9" * 5000,
    b"-" + b"9" * 5000,
    b"1e" + b"9" * 400,
    b"0." + b"0" * 400 + b"1",
    b"0x" + b"f" * 40,
    b"INF",
    b"-INF",
    b"inf",
    b"nan",
    b"-nan(1)",
    b"0x10",
    b"0x-10",
    b"+0x10",
    b"0x",
    b"1_000",
    b"1e",
    b"-",
    b"--1",
    b".",
    b"",
    b'"',
    b'""',
    b'"a b',
    b"\r",
    b"\x00",
    b"\x0b",
    b"\xff\xfe",
    b"\xe2\x84\xaa",
    b"DATA",
    b"LINES",
    b"Cairn:",
    b"Sources:",
    b"2D-Map-Ex5",
    b"#",
    b"x" * 12_100,
    b" ".join([b"t"] * 600),
    b"4294967297",
    b"9223372036854775808",
    b"-9223372036854775809",
]
NUMBER = b"0123456789"


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def _mutate(data: bytes, rng: random.Random) -> bytes:
    """One to three random edits of a file's bytes."""
    for _ in range(rng.randint(1, 3)):
        choice = rng.randrange(9)
        if not data:
            data = rng.choice(NASTY)
            continue
        i = rng.randrange(len(data))
        if choice == 0:  # flip a byte
            data = data[:i] + bytes([rng.randrange(256)]) + data[i + 1 :]
        elif choice == 1:  # insert a nasty value
            data = data[:i] + rng.choice(NASTY) + data[i:]
        elif choice == 2:  # delete a range
            data = data[:i] + data[i + rng.randint(1, 200) :]
        elif choice == 3:  # truncate
            data = data[:i]
        elif choice == 4:  # replace one number with a nasty value
            j = i
            while j < len(data) and data[j] not in NUMBER:
                j += 1
            k = j
            while k < len(data) and data[k] in NUMBER:
                k += 1
            data = data[:j] + rng.choice(NASTY) + data[k:]
        elif choice == 5:  # duplicate, drop or move a line
            lines = _lines(data)
            a, b = rng.randrange(len(lines)), rng.randrange(len(lines))
            op = rng.randrange(3)
            if op == 0:
                lines.insert(b, lines[a])
            elif op == 1:
                del lines[a]
            else:
                lines.insert(b, lines.pop(a))
            data = b"\n".join(lines)
        elif choice == 6:  # a whole line of nasty values
            lines = _lines(data)
            word = lines[rng.randrange(len(lines))].split(b" ")[0]
            lines.insert(
                rng.randrange(len(lines) + 1),
                word + b" " + b" ".join(rng.choice(NASTY) for _ in range(rng.randint(0, 12))),
            )
            data = b"\n".join(lines)
        elif choice == 7:  # CR LF, tabs or blanks
            data = data[:i] + rng.choice([b"\r\n", b"\t", b"  ", b"\n\n", b"\x0c"]) + data[i:]
        else:  # change a character's case (keywords are matched case-insensitively)
            data = data[:i] + data[i : i + 1].swapcase() + data[i + 1 :]
    return data


def _excerpt(data: bytes, head: int, rows: int) -> bytes:
    """The first ``head + rows`` lines (the header and some rows) and the last line or two."""
    lines = _lines(data)
    if len(lines) <= head + rows + 2:
        return data
    return b"\n".join(lines[: head + rows] + lines[-2:])


def _map_sources() -> Iterator[tuple[str, bytes]]:
    folders = [SHARED / "sample-data" / "real", SHARED / "sample-data" / "aria-written"]
    for folder in folders:
        for path in sorted(folder.glob("*.map")) if folder.exists() else []:
            yield f"{folder.name}/{path.name}", _excerpt(path.read_bytes(), 160, 60)
    for name in samples.list_samples():
        if name.endswith(".map"):
            yield name, _excerpt(samples.sample_path(name).read_bytes(), 80, 60)


def _log_sources() -> Iterator[tuple[str, bytes]]:
    for name in samples.list_samples():
        if name.endswith(".2d"):
            yield name, _excerpt(samples.sample_path(name).read_bytes(), 12, 120)


def _check_map(data: bytes) -> None:
    with contextlib.suppress(MapkitError):
        mapkit.loads(data, source="fuzz.map")
    try:
        m, issues = mapkit.recover(data, source="fuzz.map")
    except MapkitError:
        return
    text = mapkit.dumpb(m)
    again, _ = mapkit.recover(text)
    # Where ARIA's own rewrite is not a fixed point, neither is mapkit's (it writes what ARIA
    # writes): an unknown line starting with a quote loses that quote at every rewrite
    # (`" "x"` -> `"x"` -> `x"`), a line of a lone quote is written empty and then skipped, and
    # a quote inside a name splits it (reported as MK114). Everything else reads back the same.
    lossy = any(not line or line.startswith('"') for line in m.remainder) or any(
        i.code is IssueCode.LOSSY_QUOTE for i in issues
    )
    if not lossy:
        assert mapkit.dumpb(again) == text, "mapkit's own output is not a fixed point"
    validate(m, navigation=False)


def _check_log(data: bytes) -> None:
    with contextlib.suppress(MapkitError):
        dumps_log(loads_log(data, name="fuzz.2d"))
    try:
        log, _issues = recover_log(data, name="fuzz.2d")
    except MapkitError:
        return
    # (No fixed-point check for logs: a header cut short by a record line is written with the
    # header lines that follow it as extra lines, which read back as a second header.)
    recover_log(dumps_log(log).encode("utf-8", "surrogateescape"))


def _fuzz(
    sources: list[tuple[str, bytes]], check: Callable[[bytes], None], seed: int, tmp_path: Path
) -> int:
    assert sources, "no samples to fuzz"
    rng = random.Random(seed)
    deadline = time.monotonic() + TIME_BUDGET_S
    done = 0
    for case in range(CASES_PER_SEED):
        if time.monotonic() > deadline:
            break  # a loaded machine runs fewer cases; the seed keeps them the same ones
        name, base = sources[case % len(sources)]
        data = _mutate(base, rng)
        try:
            check(data)
        except Exception as err:  # anything but a MapkitError (or a wrong fixed point) fails
            saved = tmp_path / f"fuzz-seed{seed}-case{case}.bin"
            saved.write_bytes(data)
            pytest.fail(
                f"seed {seed} case {case} (mutated {name}, saved as {saved}): "
                f"{type(err).__name__}: {err}\n{traceback.format_exc()}"
            )
        done += 1
    return done


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_fuzz_map(seed: int, tmp_path: Path, shared_dir: Path) -> None:
    done = _fuzz(list(_map_sources()), _check_map, seed, tmp_path)
    assert done > 0


@pytest.mark.parametrize("seed", [1, 2])
def test_fuzz_2d(seed: int, tmp_path: Path) -> None:
    done = _fuzz(list(_log_sources()), _check_log, seed, tmp_path)
    assert done > 0
