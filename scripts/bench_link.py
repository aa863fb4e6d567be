#!/usr/bin/env python3
"""Benchmark of the cross-drone network path alone; prints JSON.

Two :class:`~eamos.net.link.Link` s with CURVE, each in its own process on
loopback, pass a Trigger back and forth (the echo answers from its receive
callback); half a round trip is one link hop: encode, the sequence layer, the
Out-Bridge's socket, ZeroMQ + CURVE, the In-Bridge, decode, the sequence layer
again, delivery.  In the same run: a raw ZeroMQ CURVE hop between two processes
(PUB/SUB, no EAMOS code: the floor), and micro-benchmarks of encoding and
decoding one Trigger against raw msgpack.  The node work at each end (actors,
logs) is not in it: ``scripts/bench_runtime.py --only cross_drone`` measures
the whole trigger.

Usage: ``python scripts/bench_link.py --json [--hops N]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import timeit
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

_LINK_CHILD = r"""
import json, sys, threading, time
from pathlib import Path
import zmq
from eamos.net import wire
from eamos.net.keys import FleetKeys
from eamos.net.link import Link, LinkSettings

keys_dir, me, peer, my_end, peer_end, hops, role = sys.argv[1:8]
hops = int(hops)
ctx = zmq.Context()
link = Link(ctx, me, "bench", my_end, keys=FleetKeys.load(Path(keys_dir) / me, me),
            settings=LinkSettings())
got = threading.Event()
done = threading.Event()
count = [0]

def trig(i):
    return wire.Trigger("bench", me, peer, "n1", "n2", (i,), "done")

def on_message(msg):
    if type(msg) is not wire.Trigger:
        return
    if role == "echo":
        if msg.iteration == (-1,):
            done.set()
        else:
            link.send(trig(msg.iteration[0]))
    else:
        got.set()

link.connect({peer: peer_end}, (), on_message)
assert link.wait_subscribed([wire.topic_to(peer)], 60)
if role == "echo":
    done.wait(600)
else:
    lat = []
    for i in range(hops + 50):  # the first 50 warm up (and wait for the echo to subscribe)
        got.clear()
        t0 = time.perf_counter()
        link.send(trig(i))
        assert got.wait(60), "no echo"
        if i >= 50:
            lat.append((time.perf_counter() - t0) / 2 * 1e3)
    link.send(trig(-1))
    link.flush(10)
    lat.sort()
    print(json.dumps({"hops": len(lat), "p50_ms": round(lat[len(lat) // 2], 4),
                      "p99_ms": round(lat[int(0.99 * (len(lat) - 1))], 4),
                      "retransmissions": link.retransmissions}))
link.close()
ctx.term()
"""


def bench_link_hop(hops: int) -> dict:
    """Half the round trip of a Trigger between two Links (CURVE) in two processes."""
    from eamos.ground import free_ports
    from eamos.net.keys import create_fleet_keys

    with tempfile.TemporaryDirectory() as tmp:
        keys = create_fleet_keys(Path(tmp) / "keys", ["A", "B"])
        a, b = (f"tcp://127.0.0.1:{p}" for p in free_ports(2))
        echo = subprocess.Popen(
            [sys.executable, "-c", _LINK_CHILD, str(keys), "B", "A", b, a, str(hops), "echo"],
            cwd=REPO,
        )
        try:
            ping = subprocess.run(
                [sys.executable, "-c", _LINK_CHILD, str(keys), "A", "B", a, b, str(hops), "ping"],
                capture_output=True,
                text=True,
                check=True,
                timeout=600,
                cwd=REPO,
            )
        finally:
            echo.wait(60)
    return json.loads(ping.stdout.strip().splitlines()[-1])


def bench_codec(number: int) -> dict:
    """Microseconds to encode and decode one Trigger, and raw msgpack for comparison."""
    import msgpack

    from eamos.net import wire

    msg = wire.Trigger("m-0123", "D1", "D2", "n12", "n13", (3,), "done", 17, incarnation=1 << 50)
    frames = wire.encode(msg)

    def per_call(fn) -> float:
        return round(min(timeit.repeat(fn, number=number, repeat=5)) / number * 1e6, 2)

    return {
        "payload_bytes": len(frames[1]),
        "encode_us": per_call(lambda: wire.encode(msg)),
        "decode_us": per_call(lambda: wire.decode(frames)),
        "msgpack_unpackb_us": per_call(lambda: msgpack.unpackb(frames[1])),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true", help="print JSON (the only output)")
    parser.add_argument("--hops", type=int, default=2000)
    args = parser.parse_args()
    from bench_runtime import bench_reference_hops

    out = {"codec": bench_codec(20000), "link_hop": bench_link_hop(args.hops)}
    out["zmq_curve"] = bench_reference_hops(args.hops)["zmq_curve"]
    out["link_hop"]["x_zmq_curve_p50"] = round(
        out["link_hop"]["p50_ms"] / out["zmq_curve"]["p50_ms"], 2
    )
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
