"""Build the two DDS peers (a Fast DDS C++ reader, a Cyclone DDS C reader) from Debian packages.

Used by the tests' session fixture and by benchmarks/bench_ros2.py. The programs go into a cache
folder outside the checkout (``$MAPKIT_TEST_CACHE`` or ``~/.cache/mapkit-tests``), one per hash of
the sources, and are reused while the sources stay the same.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCES = ("ros2_msgs.idl", "fastdds_reader.cpp", "cyclone_reader.c", "build.py")
DEBIAN = "libfastrtps-dev fastddsgen openjdk-17-jre-headless cyclonedds-dev cyclonedds-tools g++"


class PeerBuildError(Exception):
    """A peer could not be built (missing Debian package or compiler error)."""


def cache_dir() -> Path:
    """Where built peers live (outside the checkout)."""
    root = Path(os.environ.get("MAPKIT_TEST_CACHE", Path.home() / ".cache" / "mapkit-tests"))
    digest = hashlib.sha256(b"".join((HERE / s).read_bytes() for s in SOURCES)).hexdigest()[:16]
    return root / f"ros2-peers-{digest}"


def _run(cmd: list[str], cwd: Path) -> None:
    if shutil.which(cmd[0]) is None:
        raise PeerBuildError(f"{cmd[0]} not found; install the Debian packages: {DEBIAN}")
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        raise PeerBuildError(
            f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr[-3000:]}"
            f"\nDebian packages needed: {DEBIAN}"
        )


def build() -> dict[str, Path]:
    """Build (or reuse) both readers; ``{"fastdds": path, "cyclone": path}``.

    Raises:
        PeerBuildError: With the compiler's message and the Debian packages to install.
    """
    out = cache_dir()
    peers = {"fastdds": out / "fastdds_reader", "cyclone": out / "cyclone_reader"}
    if all(p.exists() for p in peers.values()):
        return peers
    work = out.with_name(out.name + f".tmp{os.getpid()}")
    shutil.rmtree(work, ignore_errors=True)
    (work / "fast").mkdir(parents=True)
    (work / "cyclone").mkdir()
    idl = str(HERE / "ros2_msgs.idl")
    _run(["idlc", "-t", "-Wno-implicit-extensibility", "-o", str(work / "cyclone"), idl], work)
    _run(
        [
            "gcc",
            "-O2",
            "-o",
            str(work / "cyclone_reader"),
            "-I",
            str(work / "cyclone"),
            str(HERE / "cyclone_reader.c"),
            str(work / "cyclone" / "ros2_msgs.c"),
            "-lddsc",
        ],
        work,
    )
    _run(["fastddsgen", "-replace", "-d", str(work / "fast"), idl], work)
    fast = work / "fast"
    _run(
        [
            "g++",
            "-O1",
            "-std=c++14",
            "-o",
            str(work / "fastdds_reader"),
            "-I",
            str(fast),
            str(HERE / "fastdds_reader.cpp"),
            str(fast / "ros2_msgs.cxx"),
            str(fast / "ros2_msgsPubSubTypes.cxx"),
            "-lfastrtps",
            "-lfastcdr",
        ],
        work,
    )
    try:
        work.rename(out)
    except OSError:  # another process built it first
        shutil.rmtree(work, ignore_errors=True)
    return peers


if __name__ == "__main__":
    print(build())
