"""Atomic writes (mapkit/_atomic.py): temp files of killed writers are removed by the next write
to the same file, and nothing else is."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from mapkit._atomic import STALE_AGE, atomic_write, remove_stale_temps

WRITER = """
import sys, time
from mapkit._atomic import atomic_open
with atomic_open(sys.argv[1]) as fh:
    fh.write(b"half a map")
    fh.flush()
    print("writing", flush=True)
    time.sleep(60)
"""


def _writer(target: Path) -> subprocess.Popen[str]:
    p = subprocess.Popen(
        [sys.executable, "-c", WRITER, str(target)], stdout=subprocess.PIPE, text=True
    )
    assert p.stdout is not None and p.stdout.readline() == "writing\n"
    return p


def _temps(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_a_killed_writers_temp_file_goes_with_the_next_write(tmp_path) -> None:
    target = tmp_path / "office.map"
    target.write_bytes(b"old")
    killed = [_writer(target) for _ in range(3)]
    for p in killed:
        p.send_signal(signal.SIGKILL)
        p.wait(10)
    assert len(_temps(tmp_path)) == 3 and target.read_bytes() == b"old"
    live = _writer(target)  # a writer still at work keeps its temp file
    try:
        atomic_write(target, b"new")
        assert target.read_bytes() == b"new"
        assert _temps(tmp_path) == [n for n in _temps(tmp_path) if f".{live.pid}-" in n]
        assert len(_temps(tmp_path)) == 1
    finally:
        live.kill()
        live.wait(10)
    atomic_write(target, b"newer")
    assert _temps(tmp_path) == []


def test_only_our_pattern_for_this_target_and_age_for_old_names(tmp_path) -> None:
    target = tmp_path / "a.map"
    old = time.time() - STALE_AGE - 10
    keep = [
        ".a.map.bak",
        ".a.map.tmp",
        ".a.map.short.tmp",
        ".a.map.ABCDEFGH.tmp",
        ".b.map.12345678.tmp",
        ".a.map.x.12345678.tmp",
        "a.map.12345678.tmp",
        ".a.map.12345678.tmp.json",
    ]
    for name in keep:
        (tmp_path / name).write_bytes(b"x")
        os.utime(tmp_path / name, (old, old))
    (tmp_path / ".a.map.abcd1234.tmp").write_bytes(b"recent, no pid")  # old naming, young
    (tmp_path / ".a.map.q9w8e7r6.tmp").write_bytes(b"old, no pid")
    os.utime(tmp_path / ".a.map.q9w8e7r6.tmp", (old, old))
    (tmp_path / f".a.map.{os.getpid()}-zzzzzzzz.tmp").write_bytes(b"this process, young")
    (tmp_path / ".a.map.ignored.d").mkdir()
    removed = remove_stale_temps(target)
    assert [os.path.basename(p) for p in removed] == [".a.map.q9w8e7r6.tmp"]
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == sorted(
        [*keep, ".a.map.abcd1234.tmp", f".a.map.{os.getpid()}-zzzzzzzz.tmp", ".a.map.ignored.d"]
    )


def test_the_temp_file_names_its_writer(tmp_path, monkeypatch) -> None:
    seen = []
    real = os.replace

    def spy(src, dst):
        seen.append(os.path.basename(src))
        return real(src, dst)

    monkeypatch.setattr(os, "replace", spy)
    atomic_write(tmp_path / "x.map", b"1")
    assert seen and seen[0].startswith(f".x.map.{os.getpid()}-") and seen[0].endswith(".tmp")
