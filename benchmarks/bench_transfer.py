"""Benchmark: MKT/1 over loopback against a plain Python socket copy measured in the same run.

    .venv/bin/python benchmarks/bench_transfer.py            # 256 MiB file
    .venv/bin/python benchmarks/bench_transfer.py --size 64  # MiB

Both runs move the same file from this process to another process on 127.0.0.1 that writes it
to disk:

* baseline: ``sendall`` of 1 MiB blocks read from the file; the receiver ``recv_into`` a buffer
  and writes it; nothing checked, nothing fsynced;
* MKT/1 with authentication: ``mapkit send`` logic (SHA-256 of the file for the offer, a keyed
  BLAKE2b tag and a CRC-32 per 1 MiB frame) to a real ``mapkit serve`` process (checks every
  tag, writes, SHA-256 of the whole file, fsync, rename). "first send" hashes the file before
  sending, as ``mapkit send`` always does; "file hashed before" is a file this process sent
  already (its digests are cached), which leaves only the transfer;
* the same with HMAC-SHA256 tags, and with ``--insecure`` (no tags).

Also: the CPU time of the hashes on this machine and the floor they set, and the end-to-end time
of a 1 MB map (connect, handshake, send, parse on the robot, rename): the real 1.1 MB sample
``omron-ld-showroom-ex4.map`` from ../shared when present, else a synthetic map. Temporary
files are deleted at the end. The machine is shared: every figure moves with its load, which
is printed.
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
import zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mapkit.transfer import client as client_mod, send_file  # noqa: E402

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
    proc = subprocess.Popen(
        [sys.executable, "-c", SINK, str(dst)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None
    port = int(proc.stdout.readline())
    t0 = time.perf_counter()
    with socket.create_connection(("127.0.0.1", port)) as s, open(src, "rb") as fh:
        buf = bytearray(1 << 20)
        view = memoryview(buf)
        while n := fh.readinto(buf):
            s.sendall(view[:n])
        s.shutdown(socket.SHUT_WR)
        s.recv(1)
    dt = time.perf_counter() - t0
    proc.wait()
    return dt


def start_serve(folder: Path, secret_file: Path | None) -> tuple[subprocess.Popen[str], int]:
    auth = ["--secret-file", str(secret_file)] if secret_file else ["--insecure"]
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mapkit",
            "-q",
            "serve",
            str(folder),
            "--listen",
            "127.0.0.1:0",
            *auth,
        ],
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    assert proc.stderr is not None
    line = proc.stderr.readline()
    m = re.search(r"on 127\.0\.0\.1:(\d+)", line)
    if not m:
        raise SystemExit(f"mapkit serve did not start: {line}")
    threading.Thread(target=proc.stderr.read, daemon=True).start()
    return proc, int(m.group(1))


def mkt_copy(
    src: Path,
    folder: Path,
    secret_file: Path | None,
    name: str,
    *,
    cold: bool = False,
    auth: str = "blake2b",
) -> float:
    proc, port = start_serve(folder, secret_file)
    try:
        opts: dict[str, object] = {"insecure": True}
        if secret_file:
            opts = {"secret": SECRET, "auth_methods": [auth]}
        if cold:
            client_mod._DIGESTS.clear()  # hash the file before sending, as a fresh `mapkit send`
        else:
            os.close(client_mod.offer_for_file(src)[0])  # digests cached: time the transfer
        t0 = time.perf_counter()
        r = send_file(src, "127.0.0.1", port, name=name, timeout=60, **opts)
        dt = time.perf_counter() - t0
        assert r["auth"] == (auth if secret_file else "none"), r["auth"]
        return dt
    finally:
        proc.terminate()
        proc.wait()
        (folder / name).unlink()


def cpu_speed(fn: object, data: bytes) -> float:
    """MB per second of CPU time (the machine's load inflates wall time, not CPU time)."""
    best = float("inf")
    for _ in range(3):
        t0 = time.process_time()
        fn(data)  # type: ignore[operator]
        best = min(best, time.process_time() - t0)
    return len(data) / max(best, 1e-9) / 1e6


def real_map() -> Path | None:
    shared = Path(os.environ.get("MAPKIT_SHARED", ROOT.parent / "shared"))
    p = shared / "sample-data" / "real" / "omron-ld-showroom-ex4.map"
    return p if p.is_file() else None


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
        load0 = os.getloadavg()[0]
        print(
            f"file: {size / 1e6:.0f} MB ({args.size} MiB), loopback, {os.cpu_count()} CPUs, "
            f"load average {load0:.1f}"
        )
        plain = min(plain_copy(src, work / "plain.out") for _ in range(args.runs))
        os.unlink(work / "plain.out")
        cold = min(
            mkt_copy(src, robot, secret_file, "cold.2d", cold=True) for _ in range(args.runs)
        )
        warm = min(mkt_copy(src, robot, secret_file, f"warm{i}.2d") for i in range(args.runs))
        hmac_t = mkt_copy(src, robot, secret_file, "hmac.2d", auth="hmac-sha256")
        insecure = mkt_copy(src, robot, None, "insecure.2d")
        mb = size / 1e6

        def line(what: str, t: float, note: str = "") -> None:
            print(
                f"{what:42s}{mb / t:7.1f} MB/s  ({t:5.2f} s)  ratio {plain / t:.2f}x of plain{note}"
            )

        print(f"{'plain socket copy:':42s}{mb / plain:7.1f} MB/s  ({plain:5.2f} s)")
        line("MKT/1 auth (BLAKE2b), first send:", cold, " (target >= 0.5)")
        line("MKT/1 auth (BLAKE2b), file hashed before:", warm)
        line("MKT/1 auth (HMAC-SHA256), hashed before:", hmac_t)
        line("MKT/1 --insecure, hashed before:", insecure)
        data = os.urandom(32 << 20)
        sha = cpu_speed(lambda b: hashlib.sha256(b).digest(), data)
        b2 = cpu_speed(lambda b: hashlib.blake2b(b, key=SECRET[:32], digest_size=16).digest(), data)
        crc = cpu_speed(zlib.crc32, data)
        # CPU per byte: sender SHA-256 (first send only) + BLAKE2b + CRC; robot BLAKE2b + SHA-256
        warm_cpu = 2 / b2 + 1 / crc + 1 / sha
        cold_cpu = warm_cpu + 1 / sha
        print(
            f"hash speed per core (CPU time):  SHA-256 {sha:.0f} MB/s, BLAKE2b {b2:.0f} MB/s, "
            f"CRC-32 {crc:.0f} MB/s"
        )
        print(
            f"  hashing alone, both ends on 2 idle cores: >= {2 / cold_cpu:.0f} MB/s first send, "
            f">= {2 / warm_cpu:.0f} MB/s hashed before; "
            f"the robot's SHA-256 alone: {sha:.0f} MB/s"
        )
        # a 1 MB map end to end, and the same bytes as a file the robot does not parse
        m = work / "site.map"
        sample = real_map()
        m.write_bytes(sample.read_bytes() if sample else make_map_bytes(1_000_000))
        shutil.copy(m, work / "site.2d")
        from mapkit.formats.map import parse_map

        parse_ms = min(_timed(lambda: parse_map(m.read_bytes())) for _ in range(3)) * 1000
        proc, port = start_serve(robot, secret_file)
        try:
            res = {}
            for f in (m, work / "site.2d"):
                res[f.suffix] = [
                    _timed(lambda f=f: send_file(f, "127.0.0.1", port, secret=SECRET))
                    for _ in range(7)
                ]
        finally:
            proc.terminate()
            proc.wait()
        assert (robot / "site.map").read_bytes() == m.read_bytes()
        kb = m.stat().st_size / 1e6
        which = sample.name if sample else "synthetic"
        for suffix, what in (
            (".map", f"{kb:.1f} MB map ({which}) end to end"),
            (".2d", f"{kb:.1f} MB .2d (same bytes, not parsed)   "),
        ):
            t = res[suffix]
            print(
                f"{what}: median {statistics.median(t) * 1000:5.0f} ms, "
                f"best {min(t) * 1000:5.0f} ms" + (" (target < 100 ms)" if suffix == ".map" else "")
            )
        print(f"  of which mapkit's parser on the robot: {parse_ms:.0f} ms for the map (best of 3)")
        print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _timed(fn: object) -> float:
    t0 = time.perf_counter()
    fn()  # type: ignore[operator]
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
