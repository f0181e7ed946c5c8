"""Benchmark: MKT/1 over loopback against a plain Python socket copy measured in the same run.

    .venv/bin/python benchmarks/bench_transfer.py            # 256 MiB file
    .venv/bin/python benchmarks/bench_transfer.py --size 64  # MiB

Both runs move the same file from this process to another process on 127.0.0.1 that writes it
to disk:

* baseline: ``sendall`` of 1 MiB blocks read from the file; the receiver ``recv_into`` a buffer
  and writes it; nothing checked, nothing fsynced;
* MKT/1 with authentication: ``mapkit send`` logic (SHA-256 of the file first, HMAC-SHA256 tag
  and CRC-32 per 256 KiB frame) to a real ``mapkit serve`` process (checks every tag and CRC,
  writes, SHA-256 of the whole file, fsync, rename).

Also: the same with ``--insecure`` (no HMAC), the machine's SHA-256 speed (the floor of the
authenticated transfer: the receiver hashes every byte twice, the sender twice), and the
end-to-end time of a 1 MB map (connect, handshake, send, parse on the robot, rename).
Temporary files are deleted at the end.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mapkit.transfer import send_file  # noqa: E402

SECRET = b"benchmark-secret-0123456789abcdef"

SINK = r"""
import socket, sys
srv = socket.create_server(("127.0.0.1", 0))
print(srv.getsockname()[1], flush=True)
conn, _ = srv.accept()
buf = bytearray(1 << 20)
view = memoryview(buf)
with open(sys.argv[1], "wb") as fh:
    while True:
        n = conn.recv_into(view)
        if not n:
            break
        fh.write(view[:n])
conn.sendall(b"k")
"""


def make_file(path: Path, size: int) -> None:
    block = os.urandom(1 << 20)
    with open(path, "wb") as fh:
        left = size
        while left > 0:
            fh.write(block[: min(left, len(block))])
            left -= len(block)
            block = block[1:] + block[:1]  # not one repeated block


def plain_copy(src: Path, dst: Path) -> float:
    proc = subprocess.Popen([sys.executable, "-c", SINK, str(dst)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    port = int(proc.stdout.readline())
    t0 = time.perf_counter()
    with socket.create_connection(("127.0.0.1", port)) as s, open(src, "rb") as fh:
        buf = bytearray(1 << 20)
        view = memoryview(buf)
        while (n := fh.readinto(buf)):
            s.sendall(view[:n])
        s.shutdown(socket.SHUT_WR)
        s.recv(1)
    dt = time.perf_counter() - t0
    proc.wait()
    return dt


def start_serve(folder: Path, secret_file: Path | None) -> tuple[subprocess.Popen[str], int]:
    auth = ["--secret-file", str(secret_file)] if secret_file else ["--insecure"]
    proc = subprocess.Popen([sys.executable, "-m", "mapkit", "-q", "serve", str(folder), "--listen",
                             "127.0.0.1:0", *auth], stderr=subprocess.PIPE, text=True, cwd=ROOT)
    assert proc.stderr is not None
    line = proc.stderr.readline()
    m = re.search(r"on 127\.0\.0\.1:(\d+)", line)
    if not m:
        raise SystemExit(f"mapkit serve did not start: {line}")
    threading.Thread(target=proc.stderr.read, daemon=True).start()
    return proc, int(m.group(1))


def mkt_copy(src: Path, folder: Path, secret_file: Path | None, name: str) -> float:
    proc, port = start_serve(folder, secret_file)
    try:
        opts = {"secret": SECRET} if secret_file else {"insecure": True}
        t0 = time.perf_counter()
        send_file(src, "127.0.0.1", port, name=name, timeout=60, **opts)
        return time.perf_counter() - t0
    finally:
        proc.terminate()
        proc.wait()


def sha_speed() -> float:
    data = os.urandom(32 << 20)
    t0 = time.perf_counter()
    hashlib.sha256(data).digest()
    return len(data) / (time.perf_counter() - t0) / 1e6


def make_map_bytes(target: int) -> bytes:
    import random

    rng = random.Random(1)
    lines = ["2D-Map", 'Cairn: Goal 1000 2000 0 "" ICON "Desk"', "DATA"]
    size = sum(len(x) + 1 for x in lines)
    while size < target:
        row = f"{rng.randrange(-60000, 60000)} {rng.randrange(-60000, 60000)}"
        lines.append(row)
        size += len(row) + 1
    return ("\n".join(lines) + "\n").encode()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256, help="file size in MiB (default 256)")
    ap.add_argument("--runs", type=int, default=2, help="runs of each big copy; the best counts")
    args = ap.parse_args()
    size = args.size << 20
    work = Path(tempfile.mkdtemp(prefix="mapkit-bench-"))
    try:
        secret_file = work / "secret"
        secret_file.write_bytes(SECRET)
        src = work / "big.2d"
        make_file(src, size)
        robot = work / "robot"
        robot.mkdir()
        print(f"file: {size / 1e6:.0f} MB ({args.size} MiB), loopback, {os.cpu_count()} CPUs, "
              f"load average {os.getloadavg()[0]:.1f}")
        plain = min(plain_copy(src, work / "plain.out") for _ in range(args.runs))
        os.unlink(work / "plain.out")
        auth = min(mkt_copy(src, robot, secret_file, f"auth{i}.2d") for i in range(args.runs))
        for p in robot.glob("auth*.2d"):
            p.unlink()
        insecure = mkt_copy(src, robot, None, "insecure.2d")
        (robot / "insecure.2d").unlink()
        mb = size / 1e6
        print(f"plain socket copy:           {mb / plain:8.1f} MB/s  ({plain:.2f} s)")
        print(f"MKT/1, HMAC-SHA256 auth:     {mb / auth:8.1f} MB/s  ({auth:.2f} s)  "
              f"ratio {plain / auth:.2f}x of plain (target >= 0.5)")
        print(f"MKT/1, --insecure:           {mb / insecure:8.1f} MB/s  ({insecure:.2f} s)  "
              f"ratio {plain / insecure:.2f}x of plain")
        sha = sha_speed()
        print(f"SHA-256 on this CPU:         {sha:8.1f} MB/s per core; authenticated MKT hashes each "
              f"byte 4 times (2 per side): hash-bound ceiling ~{sha / 2:.0f} MB/s on 2 cores")
        # a 1 MB map end to end, and the same bytes as a file the robot does not parse
        m = work / "site.map"
        m.write_bytes(make_map_bytes(1_000_000))
        shutil.copy(m, work / "site.2d")
        from mapkit.formats.map import parse_map

        t0 = time.perf_counter()
        parse_map(m.read_bytes())
        parse_ms = (time.perf_counter() - t0) * 1000
        proc, port = start_serve(robot, secret_file)
        try:
            res = {}
            for f in (m, work / "site.2d"):
                times = []
                for _ in range(7):
                    t0 = time.perf_counter()
                    send_file(f, "127.0.0.1", port, secret=SECRET)
                    times.append(time.perf_counter() - t0)
                res[f.suffix] = times
        finally:
            proc.terminate()
            proc.wait()
        assert (robot / "site.map").read_bytes() == m.read_bytes()
        for suffix, what in ((".map", "1 MB map end to end (connect, auth, send, parse, rename)"),
                             (".2d", "1 MB .2d end to end (connect, auth, send, rename)     ")):
            t = res[suffix]
            print(f"{what}: median {statistics.median(t) * 1000:5.0f} ms, best {min(t) * 1000:5.0f} ms"
                  + (" (target < 100 ms)" if suffix == ".map" else ""))
        print(f"  of which mapkit's parser on the robot: {parse_ms:.0f} ms for the 1 MB map")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
