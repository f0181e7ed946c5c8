"""A hostile node on a mapkit channel: publishes raw MKT/1 frames to every robot it hears of.

Run as ``python tests/ros/hostile_peer.py CHANNEL MODE SEED COUNT`` against a running roscore
(``ROS_MASTER_URI``). MODE ``deep`` sends unauthenticated frames whose JSON nests 100,000 deep
(and other hostile texts); ``flood`` starts COUNT handshakes and finishes none; ``fuzz`` sends
COUNT fuzzed frames (see tests/transfer/mkt_fuzz.py),
unauthenticated and, with ``MAPKIT_SECRET`` set, inside an authenticated session. Prints
``sent N`` and exits.
"""

from __future__ import annotations

import json
import os
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "transfer"))
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import contextlib

from mkt_fuzz import _RAW_TEXTS, frame_types, mutate_bytes, mutate_payload

from mapkit.ros.node import rospy, start_node
from mapkit.transfer.protocol import (
    Channel,
    ClientHandshake,
    FrameType,
    Out,
    encode_frame,
)


def main() -> None:
    channel, mode, seed, count = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    rp = rospy()
    start_node("hostile_peer")
    from std_msgs.msg import MultiArrayDimension, MultiArrayLayout, String, UInt8MultiArray

    robots: set[str] = set()
    replies: list[bytes] = []
    me = rp.get_name()

    def announce(msg: String) -> None:
        with contextlib.suppress(ValueError, KeyError, TypeError):
            robots.add(json.loads(msg.data)["node"])

    def reply(msg: UInt8MultiArray) -> None:
        dims = msg.layout.dim
        if dims and dims[0].label.endswith(" " + me):
            replies.append(bytes(msg.data))

    rp.Subscriber(f"mapkit/{channel}/announce", String, announce)
    rp.Subscriber(f"mapkit/{channel}/r2c", UInt8MultiArray, reply)
    pub = rp.Publisher(f"mapkit/{channel}/c2r", UInt8MultiArray, queue_size=1000)
    end = time.monotonic() + 20
    while (not robots or pub.get_num_connections() < 1) and time.monotonic() < end:
        time.sleep(0.05)
    if not robots:
        sys.exit("no robot announced itself")
    time.sleep(0.5)

    def send(frame: bytes) -> None:
        for node in robots:
            dim = MultiArrayDimension(label=f"{me} {node}", size=len(frame), stride=len(frame))
            layout = MultiArrayLayout(dim=[dim], data_offset=0)
            pub.publish(UInt8MultiArray(layout=layout, data=frame))

    rng = random.Random(seed)
    sent = 0
    if mode == "deep":
        for i, make in enumerate(_RAW_TEXTS):
            for ftype in (FrameType.HELLO, FrameType.AUTH, FrameType.OFFER):
                send(b"".join(encode_frame(ftype, make(rng), session=1000 + i * 8 + ftype, seq=1)))
                sent += 1
        deep = b"[" * 100_000
        send(b"".join(encode_frame(FrameType.HELLO, deep, session=999, seq=1)))
        sent += 1
    elif mode == "flood":  # COUNT handshakes started and never finished
        from mapkit.transfer.protocol import dump_json

        hello = dump_json(
            {
                "versions": [1],
                "nonce": "ab" * 32,
                "auth": ["blake2b"],
                "peer": "flood",
                "software": "x",
            }
        )
        for i in range(count):
            send(b"".join(encode_frame(FrameType.HELLO, hello, session=5000 + i, seq=1)))
            sent += 1
    else:
        secret = os.environ.get("MAPKIT_SECRET", "").encode() or None
        for i in range(count):
            c = Channel(initiator=True, session=rng.randrange(1, 1 << 64), ordered=False)
            if secret is not None and i % 2:  # an authenticated session first
                hs = ClientHandshake(c, secret, peer="hostile")
                for o in hs.start(time.monotonic()):
                    send(c.encode(o))
                t_end = time.monotonic() + 3
                while not hs.finished and time.monotonic() < t_end:
                    while replies:
                        c.receive_message(replies.pop(0))
                        while (ev := c.next_event()) is not None:
                            for o in hs.handle(ev, time.monotonic()):
                                send(c.encode(o))
                    time.sleep(0.01)
            for _ in range(rng.randrange(1, 4)):
                t = frame_types(rng)
                data = c.encode(Out(t, mutate_payload(t, rng), ref=rng.choice([0, 1, 2])))  # type: ignore[arg-type]
                send(mutate_bytes(data, rng) if rng.random() < 0.3 else data)
                sent += 1
    time.sleep(1.0)  # let the last messages leave before the node goes
    print(f"sent {sent}", flush=True)


if __name__ == "__main__":
    main()
