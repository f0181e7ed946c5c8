"""Moving a 50 MB map through a real roscore on loopback: mapkit vs one std_msgs/String per line.

The baseline is the original design: the map file published line by line on a String topic,
the subscriber appending each line to a file. It has no end marker, no check and no resend; here
the subscriber is told the line count in advance so that the clock stops at the last line, and
the benchmark compares the result with the original afterwards (the baseline itself cannot).

mapkit: ``mapkit.ros.transfer.push`` (MKT/1 frames in std_msgs/UInt8MultiArray, HMAC per frame,
acks, resend, SHA-256 checked by the receiver before the file is renamed into place) to a
``mapkit ros receive`` process. The clock runs from reading the file to the receiver's VERIFIED
frame, finding the robot on the channel and the handshake included (best of 3). The map's bytes
are sent under a ``.2d`` name: a received ``.map`` is also parsed before it is accepted, and
that parse (mapkit's reader, not the transport) is timed on its own with ``--parse``.

Both run in the same invocation, against the same roscore (started here on a free port).

    python benchmarks/bench_ros.py            # 50 MB
    python benchmarks/bench_ros.py --mb 5     # quicker
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SECRET = "benchmark secret of at least sixteen bytes"


def make_map(path: Path, mb: float) -> int:
    """A .map of about ``mb`` megabytes: a point cloud on a 20 mm lattice plus some lines."""
    import numpy as np

    from mapkit import MapData, MapObject, Scan, save

    n = int(mb * 1e6 / 12.5)
    rng = np.random.default_rng(7)
    pts = rng.integers(-50_000, 50_000, size=(n, 2)) // 20 * 20
    lines = rng.integers(-50_000, 50_000, size=(2000, 4))
    m = MapData(
        scans=(Scan.from_arrays(pts, lines, resolution=20),),
        objects=(MapObject("RobotHome", 0, 0, name="Home"),),
    )
    save(m, path)
    return path.stat().st_size


def lines_receiver(out: str, count: int) -> None:
    """The baseline's subscriber: one String per line, appended to a file, until ``count`` lines."""
    import threading

    import rospy
    from std_msgs.msg import String

    rospy.init_node("baseline_receiver", anonymous=True, disable_signals=True)
    done = threading.Event()
    got: list[str] = []

    def cb(msg: String) -> None:
        got.append(msg.data)
        if len(got) >= count:
            done.set()

    rospy.Subscriber("baseline/lines", String, cb, queue_size=None, tcp_nodelay=True)
    print("ready", flush=True)
    done.wait(600)
    with open(out, "w", encoding="utf-8", newline="") as fh:
        fh.write("".join(got))


def run_baseline(ros_env: dict[str, str], data: bytes, tmp: Path) -> tuple[float, bool, int]:
    import rospy
    from std_msgs.msg import String

    warnings.filterwarnings("ignore", message="The publisher should be created")
    text = data.decode("utf-8")
    lines = text.splitlines(keepends=True)
    out = tmp / "baseline.map"
    argv = [sys.executable, __file__, "--lines-receiver", str(out), str(len(lines))]
    proc = subprocess.Popen(argv, env=ros_env, stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "ready"
    # queue_size=None: synchronous publish, the baseline's best case (a queue would drop lines)
    pub = rospy.Publisher("baseline/lines", String, queue_size=None)
    while pub.get_num_connections() < 1:
        time.sleep(0.01)
    time.sleep(0.5)
    t0 = time.perf_counter()
    for line in lines:
        pub.publish(String(data=line))
    proc.wait(900)
    seconds = time.perf_counter() - t0
    got = out.read_bytes() if out.exists() else b""
    return seconds, got == data, len(got)


def run_mapkit(
    ros_env: dict[str, str], path: Path, tmp: Path, name: str = "big.2d", repeat: int = 3
) -> tuple[list[float], bool, dict[str, object]]:
    """Push ``path`` ``repeat`` times (under fresh names) to one receiver; the times."""
    from mapkit.ros.transfer import push

    dest = tmp / "mapkit_rx"
    env = dict(ros_env, MAPKIT_SECRET=SECRET)
    rx = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "mapkit",
            "ros",
            "receive",
            "-o",
            str(dest),
            "--name",
            "bench",
            "--channel",
            "bench",
            "--count",
            str(repeat),
        ],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    assert rx.stderr is not None
    rx.stderr.readline()  # its banner: the node is up and announcing
    times, ok, extra = [], True, {}
    for k in range(repeat):
        each = f"{k}.{name}"
        t0 = time.perf_counter()
        (res,) = push(
            str(path),
            channel="bench",
            secret=SECRET.encode(),
            name=each,
            expect=1,
            wait=30,
            idle_timeout=300,
        )
        times.append(time.perf_counter() - t0)
        ok = ok and res.ok and (dest / each).read_bytes() == path.read_bytes()
        extra = {"chunks_sent": res.chunks_sent, "resent": res.chunks_resent}
        (dest / each).unlink()
    rx.wait(60)
    return times, ok, extra


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mb", type=float, default=50.0, help="Size of the map in MB.")
    ap.add_argument(
        "--parse",
        action="store_true",
        help="Also push it as a .map, which the receiver parses before accepting it.",
    )
    ap.add_argument(
        "--no-baseline", action="store_true", help="Skip the (slow) line-per-message run."
    )
    ap.add_argument("--lines-receiver", nargs=2, metavar=("OUT", "COUNT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.lines_receiver:
        lines_receiver(args.lines_receiver[0], int(args.lines_receiver[1]))
        return

    from mapkit.ros.node import start_node
    from tests.ros.conftest import ROS_APT, ros_missing, running_roscore

    if ros_missing():
        sys.exit(f"ROS 1 is missing ({ros_missing()}): sudo apt-get install {ROS_APT}")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        path = tmp / "big.map"
        size = make_map(path, args.mb)
        data = path.read_bytes()
        lines = data.count(b"\n")
        digest = hashlib.sha256(data).hexdigest()
        print(f"map: {size / 1e6:.1f} MB, {lines} lines, SHA-256 {digest[:16]}…")
        with running_roscore(tmp) as ros:
            os.environ.update({k: v for k, v in ros.env.items() if k.startswith("ROS_")})
            start_node("bench_ros")
            times, mk_ok, extra = run_mapkit(ros.env, path, tmp)
            mk_s = min(times)
            print(
                "mapkit (MKT/1 over UInt8MultiArray, HMAC, acks, SHA-256 verified): best of "
                f"{len(times)} {mk_s:.2f} s ({', '.join(f'{t:.2f}' for t in times)}), "
                f"{size / 1e6 / mk_s:.1f} MB/s, verified {'yes' if mk_ok else 'NO'} ({extra})"
            )
            if args.parse:
                p_times, p_ok, _ = run_mapkit(ros.env, path, tmp, name="big.map", repeat=1)
                print(
                    f"mapkit, sent as .map (the receiver also parses it): {p_times[0]:.2f} s, "
                    f"verified {'yes' if p_ok else 'NO'}"
                )
            if args.no_baseline:
                return
            bl_s, bl_ok, got = run_baseline(ros.env, data, tmp)
            print(
                f"baseline (one std_msgs/String per line, {lines} messages): {bl_s:.2f} s, "
                f"{size / 1e6 / bl_s:.2f} MB/s, {lines / bl_s:.0f} lines/s; "
                f"identical {'yes' if bl_ok else f'NO ({got} of {size} bytes)'} "
                "(checked by the benchmark: the baseline cannot tell)"
            )
            print(f"ratio: mapkit is {bl_s / mk_s:.0f}x faster")


if __name__ == "__main__":
    main()
