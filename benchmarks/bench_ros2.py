"""A late-joining ROS 2 reader receiving a 2000 x 2000 map, against the same bytes over plain TCP.

mapkit publishes a 2000 x 2000 nav_msgs/OccupancyGrid (4 MB of CDR) as nav2's map_server does
(reliable, transient-local, depth 1). Then, one at a time, a reader is started and the clock
runs from its start until it has the whole map: the Fast DDS C++ reader (as rmw_fastrtps; its
default socket buffers) and the Cyclone DDS C reader (as rmw_cyclonedds), both built from
tests/ros2/peers. Baseline, in the same run: a client process started the same way that
connects to a loopback TCP server holding the same bytes and reads them all. Everything runs in
a private network namespace (root or unprivileged user namespaces needed). Best and median of N.

    python benchmarks/bench_ros2.py            # 5 runs each
    python benchmarks/bench_ros2.py --runs 10
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.ros2.netns import NetNs  # noqa: E402
from tests.ros2.peers.build import build  # noqa: E402

PUBLISHER = """
import sys, numpy as np
from mapkit.raster.grid import OccupancyGrid
from mapkit.ros2.dds import Node
from mapkit.ros2.messages import OCCUPANCY_GRID, grid_cdr
cells = np.random.default_rng(1).choice(np.array([-1, 0, 100], np.int8), (2000, 2000))
cdr = grid_cdr(OccupancyGrid(cells, 0.05, (-50.0, -50.0)), stamp=1.0)
node = Node("bench_map_server", 11)
node.writer("bench_map", OCCUPANCY_GRID).write(cdr)
open(sys.argv[1], "wb").write(cdr)
print("PUBLISHED", flush=True)
sys.stdin.read()
"""

TCP_SERVER = """
import socket, sys
data = open(sys.argv[1], "rb").read()
srv = socket.socket(); srv.bind(("127.0.0.1", 0)); srv.listen(8)
print(srv.getsockname()[1], flush=True)
while True:
    c, _ = srv.accept(); c.sendall(data); c.close()
"""

TCP_CLIENT = """
import socket, sys
s = socket.create_connection(("127.0.0.1", int(sys.argv[1]))); n = 0
while True:
    b = s.recv(1 << 20)
    if not b: break
    n += len(b)
assert n == int(sys.argv[2]), n
"""


def timed(cmd: list[str], until: str | None) -> float:
    """Seconds from starting ``cmd`` to its line starting with ``until`` (or to its exit)."""
    t = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    if until is not None:
        for line in proc.stdout:
            if line.startswith(until):
                break
        else:
            raise SystemExit(f"{cmd[0]} ended without {until!r}")
    elapsed = time.perf_counter() - t
    proc.communicate(timeout=60)
    if proc.returncode != 0:
        raise SystemExit(f"{cmd} failed ({proc.returncode})")
    return elapsed if until is not None else time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args()
    peers = build()
    ns = NetNs().start()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with tempfile.TemporaryDirectory() as tmp:
        payload = os.path.join(tmp, "map.cdr")
        pub = subprocess.Popen(
            ns.wrap([sys.executable, "-c", PUBLISHER, payload]),
            env=env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert pub.stdout is not None
        assert pub.stdout.readline().strip() == "PUBLISHED"
        tcp = subprocess.Popen(
            ns.wrap([sys.executable, "-c", TCP_SERVER, payload]), stdout=subprocess.PIPE, text=True
        )
        try:
            assert tcp.stdout is not None
            port = tcp.stdout.readline().strip()
            size = os.path.getsize(payload)
            results: dict[str, list[float]] = {}
            for _ in range(args.runs):
                for name in ("fastdds", "cyclone"):
                    cmd = ns.wrap([str(peers[name]), "11", tmp, "30", "grid:rt/bench_map:1"])
                    results.setdefault(f"{name} reader (DDS)", []).append(timed(cmd, "grid "))
                cmd = ns.wrap([sys.executable, "-S", "-c", TCP_CLIENT, port, str(size)])
                results.setdefault("TCP client (baseline)", []).append(timed(cmd, None))
        finally:
            pub.stdin.close()  # type: ignore[union-attr]
            pub.wait(20)
            tcp.kill()
            tcp.wait()
            ns.stop()
    base = statistics.median(results["TCP client (baseline)"])
    print(
        f"2000 x 2000 map, {size / 1e6:.1f} MB of CDR; late joiner's start -> map received "
        f"({args.runs} runs)"
    )
    for name, ts in results.items():
        med = statistics.median(ts)
        print(
            f"  {name:24s} best {min(ts) * 1000:8.1f} ms  median {med * 1000:8.1f} ms  "
            f"x{med / base:6.1f} of TCP"
        )


if __name__ == "__main__":
    main()
