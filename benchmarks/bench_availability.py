"""Benchmark: an honest terminal's request time on a real `mapkit serve`, quiet and under attack.

    .venv/bin/python benchmarks/bench_availability.py [--seconds 5]

Starts ``mapkit serve`` on 127.0.0.1 and times ``list_maps`` (connect, handshake, LIST, BYE)
repeatedly: first with nobody else connected (the baseline, same run), then while attacker
threads open silent TCP connections as fast as they can and re-open whatever the robot closes,
from one address and from 40 (127.0.0.2-41). Prints the median and 95th percentile of each and
their ratio to the baseline, and how many requests failed (the goal: none).
"""

from __future__ import annotations

import argparse
import os
import re
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from mapkit.errors import TransferError
from mapkit.transfer import list_maps

SECRET = b"benchmark secret, 32 bytes long!"


def _serve(folder: Path, secret_file: Path) -> tuple[subprocess.Popen[bytes], int]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env.pop("MAPKIT_SECRET", None)
    log = folder.parent / "serve.log"
    cmd = [sys.executable, "-m", "mapkit", "serve", str(folder), "--listen", "127.0.0.1:0"]
    with open(log, "wb") as err:  # the server keeps its own copy of the descriptor
        proc = subprocess.Popen(
            [*cmd, "--secret-file", str(secret_file)],
            stderr=err,
            stdout=subprocess.DEVNULL,
            env=env,
        )
    end = time.monotonic() + 60
    while time.monotonic() < end:
        m = re.search(r"on 127\.0\.0\.1:(\d+) \(", log.read_text(errors="replace"))
        if m:
            return proc, int(m.group(1))
        time.sleep(0.05)
    raise SystemExit("mapkit serve did not start")


def _attack(port: int, sources: list[str], stop: threading.Event, opened: list[int]) -> None:
    held: list[socket.socket] = []
    i = 0
    while not stop.is_set():
        s = socket.socket()
        try:
            s.bind((sources[i % len(sources)], 0))
            s.connect(("127.0.0.1", port))
            held.append(s)
            opened[0] += 1
        except OSError:
            s.close()
            time.sleep(0.005)
        i += 1
        if len(held) > 400:
            held.pop(0).close()
    for s in held:
        s.close()


def _measure(port: int, seconds: float) -> tuple[list[float], int]:
    times, failed = [], 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        t = time.perf_counter()
        try:
            list_maps("127.0.0.1", port, secret=SECRET, timeout=10.0)
            times.append(time.perf_counter() - t)
        except TransferError:
            failed += 1
    return times, failed


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "maps"
        folder.mkdir()
        secret_file = Path(tmp) / "secret"
        secret_file.write_bytes(SECRET)
        proc, port = _serve(folder, secret_file)
        try:
            rows = []
            for label, sources, threads in (
                ("quiet (baseline)", [], 0),
                ("silent flood, 1 address", ["127.0.0.1"], 2),
                ("silent flood, 40 addresses", [f"127.0.0.{i}" for i in range(2, 42)], 2),
            ):
                stop, opened = threading.Event(), [0]
                workers = [
                    threading.Thread(
                        target=_attack, args=(port, sources, stop, opened), daemon=True
                    )
                    for _ in range(threads)
                ]
                for w in workers:
                    w.start()
                time.sleep(0.5 if threads else 0)
                times, failed = _measure(port, args.seconds)
                stop.set()
                for w in workers:
                    w.join(10)
                rows.append((label, times, failed, opened[0]))
            base = statistics.median(rows[0][1])
            print(
                f"{'honest list_maps':<30}{'median':>10}{'p95':>10}{'ratio':>8}{'failed':>8}"
                f"{'attacker conns':>16}"
            )
            for label, times, failed, opened in rows:
                med = statistics.median(times)
                p95 = statistics.quantiles(times, n=20)[-1] if len(times) > 1 else med
                print(
                    f"{label:<30}{med * 1e3:>8.1f}ms{p95 * 1e3:>8.1f}ms{med / base:>7.2f}x"
                    f"{failed:>8}{opened:>16}"
                )
            print(f"load average: {os.getloadavg()[0]:.1f}")
        finally:
            proc.terminate()
            proc.wait(20)


if __name__ == "__main__":
    main()
