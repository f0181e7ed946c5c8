"""Benchmark: ``mapkit aria fetch`` against ARIA's own client (``run-probe get``), same run.

    .venv/bin/python benchmarks/bench_aria.py [--repeat 5]

ARIA 2.9.1's own server (``run-mapserver`` from ../shared/aria-peer, or $MAPKIT_ARIA_PEER) serves
two maps: the 1,000,000-point benchmark map (``benchmarks/bigmap.py``, about 13 MB) and a 1.2 MB
one (every 17th point of it, same objects). For each, with that map active on the server:

* baseline: ARIA's client ``run-probe get . MAP OUT`` as a whole process (connect, log in,
  getFile, write; nothing checked);
* mapkit: ``mapkit aria fetch HOST -o OUT`` as a whole process (Python start, connect, log in,
  getMapName + getMapId, getFile, MD5 against the robot's map id, parse the whole map, write
  atomically with fsync); and the same command run through the ``aria`` click group alone,
  which is what it costs once ``mapkit``'s top-level group imports command modules lazily;
  and ``Robot.save_map`` in this (already running) Python: the protocol, verification and parse
  without the interpreter's start and imports.

Both log in as a user (the server has a user file). The best of ``--repeat`` runs each, run
alternately, and the ratio are printed; target: mapkit no slower than 1.2x ARIA's client. Both
outputs are compared byte for byte with the served file. The machine is shared: the figures move
with its load, which is printed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.bigmap import make_big_map  # noqa: E402
from mapkit import save  # noqa: E402
from mapkit.aria import connect  # noqa: E402

PEER = Path(os.environ.get("MAPKIT_ARIA_PEER", ROOT.parent / "shared" / "aria-peer"))
MAPKIT = [sys.executable, "-m", "mapkit"]
if (Path(sys.executable).parent / "mapkit").exists():
    MAPKIT = [str(Path(sys.executable).parent / "mapkit")]


#: The same command loaded through its own click group only (what `mapkit` costs once its
#: top-level group loads command modules lazily).
GROUP_ONLY = (
    "import sys; from mapkit.cli.aria import aria; aria(sys.argv[1:], prog_name='mapkit aria')"
)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def probe(port: int, *args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [
            str(PEER / "run-probe"),
            "-quiet",
            "-port",
            str(port),
            "-user",
            "bench",
            "-password",
            "bench1",
            *args,
        ],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=300,
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if not (PEER / "run-mapserver").exists():
        print(f"ARIA's peer not found at {PEER} (set MAPKIT_ARIA_PEER)", file=sys.stderr)
        return 2
    work = Path(tempfile.mkdtemp(prefix="bench-aria-"))
    proc = None
    try:
        root = work / "root"
        root.mkdir()
        big = make_big_map()
        save(big, root / "big.map")
        small = big.with_scan(big.scan.with_data(points=np.ascontiguousarray(big.points[::17])))
        save(small, root / "small.map")
        (work / "users").write_text("UserInfoVersion1\nuser bench bench1 all\n")
        port = free_port()
        proc = subprocess.Popen(
            [
                str(PEER / "run-mapserver"),
                "-serverPort",
                str(port),
                "-fileDir",
                str(root),
                "-userInfo",
                str(work / "users"),
                "-config",
                str(work / "server.cfg"),
                "-tempDir",
                str(work),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for _ in range(100):
            if probe(port, "mapname", cwd=work).returncode == 0:
                break
            time.sleep(0.1)
        env = dict(os.environ, MAPKIT_ARIA_PASSWORD="bench1")
        env.pop("MAPKIT_ARIA_PASSWORD_FILE", None)
        print(
            f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; "
            f"best of {args.repeat} runs each"
        )
        for name in ("small.map", "big.map"):
            served = (root / name).read_bytes()
            res = probe(port, "setmap", name, "60", cwd=work)
            assert f"mapname: '{name}'" in res.stdout, res.stdout
            t_aria: list[float] = []
            t_mapkit: list[float] = []
            t_group: list[float] = []
            t_inproc: list[float] = []
            for i in range(args.repeat):
                out_a, out_m = work / f"a-{i}.map", work / f"m-{i}.map"
                t = time.perf_counter()
                r = probe(port, "get", ".", name, str(out_a), cwd=work)
                t_aria.append(time.perf_counter() - t)
                assert r.returncode == 0 and out_a.read_bytes() == served, r.stdout
                t = time.perf_counter()
                r2 = subprocess.run(
                    [
                        *MAPKIT,
                        "aria",
                        "fetch",
                        f"127.0.0.1:{port}",
                        "-u",
                        "bench",
                        "-o",
                        str(out_m),
                    ],
                    capture_output=True,
                    text=True,
                    env=env,
                    cwd=work,
                    timeout=300,
                )
                t_mapkit.append(time.perf_counter() - t)
                assert r2.returncode == 0 and "matches the robot's map id" in r2.stdout, r2.stderr
                assert out_m.read_bytes() == served
                out_m.unlink()
                t = time.perf_counter()
                r3 = subprocess.run(
                    [
                        sys.executable,
                        "-c",
                        GROUP_ONLY,
                        "fetch",
                        f"127.0.0.1:{port}",
                        "-u",
                        "bench",
                        "-o",
                        str(out_m),
                    ],
                    capture_output=True,
                    text=True,
                    env=env,
                    cwd=work,
                    timeout=300,
                )
                t_group.append(time.perf_counter() - t)
                assert r3.returncode == 0 and out_m.read_bytes() == served, r3.stderr
                out_m.unlink()
                t = time.perf_counter()
                with connect(f"127.0.0.1:{port}", user="bench", password="bench1") as robot:
                    robot.save_map(out_m)
                t_inproc.append(time.perf_counter() - t)
                assert out_m.read_bytes() == served
                out_a.unlink()
                out_m.unlink()
            a, m, g, i_ = min(t_aria), min(t_mapkit), min(t_group), min(t_inproc)
            print(
                f"{name:9s} {len(served) / 1e6:5.1f} MB: ARIA run-probe get {a:6.3f} s, "
                f"mapkit aria fetch {m:6.3f} s (verified + parsed): {m / a:4.2f}x; "
                f"through the aria group alone {g:6.3f} s: {g / a:4.2f}x; "
                f"in a running Python (connect, fetch, verify, parse, write) {i_:6.3f} s: "
                f"{i_ / a:4.2f}x"
            )
        start = min(_timed([*MAPKIT, "--version"]) for _ in range(args.repeat))
        bare = min(_timed([sys.executable, "-c", "pass"]) for _ in range(args.repeat))
        print(f"(process start alone: `mapkit --version` {start:.3f} s, bare Python {bare:.3f} s)")
    finally:
        if proc is not None:
            proc.terminate()
            proc.wait(15)
        shutil.rmtree(work, ignore_errors=True)
    return 0


def _timed(cmd: list[str]) -> float:
    t = time.perf_counter()
    subprocess.run(cmd, capture_output=True)
    return time.perf_counter() - t


if __name__ == "__main__":
    sys.exit(main())
