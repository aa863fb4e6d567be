"""An intruder on the fleet's network, run in its own namespace by the fault tests.

It has its own key pairs (a separate ``eamos keys`` run with the fleet's
participant names) and knows everything public: every endpoint, the fleet's
public keys, the mission id, the wire format and the node names.  While the
mission runs it

* binds a CURVE server posing as ``--pose`` (with its own key for that name and
  a ZAP handler admitting anyone) and publishes forged Triggers and an Abort
  claiming to come from ``--pose``, with plausible sequence numbers; the test
  redirects one drone's connections for ``--pose`` here (DNAT);
* connects to every fleet Out-Bridge as a CURVE client with its own key,
  subscribed to everything;
* connects to every fleet Out-Bridge with a plain (NULL) socket too;

then writes a JSON result: what it received and whether anyone subscribed.
It stops when ``--stop-file`` appears (the fleet is done), or after ``--seconds``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator

from eamos.net import wire
from eamos.net.keys import FleetKeys
from eamos.net.zap import participant_domain


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--keys", type=Path, required=True, help="the intruder's own key folder")
    parser.add_argument("--fleet-public", type=Path, required=True, help="the fleet's public keys")
    parser.add_argument("--bind", required=True)
    parser.add_argument("--pose", required=True)
    parser.add_argument("--target", required=True, help="the drone receiving forged triggers")
    parser.add_argument("--nodes", required=True, help="comma-separated node keys on --target")
    parser.add_argument("--peer", action="append", default=[], metavar="NAME=ENDPOINT")
    parser.add_argument("--mission", required=True)
    parser.add_argument("--seconds", type=float, default=120.0, help="at most this long")
    parser.add_argument("--stop-file", type=Path, help="stop as soon as this file exists")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()

    own = FleetKeys.load(args.keys, args.pose)
    public = {
        p.name.removesuffix(".key"): zmq.auth.load_certificate(p)[0]
        for p in sorted(args.fleet_public.glob("*.key"))
    }
    ctx: zmq.Context[Any] = zmq.Context()
    auth = ThreadAuthenticator(ctx)
    auth.start()
    auth.configure_curve(domain=participant_domain(args.pose), location=zmq.auth.CURVE_ALLOW_ANY)

    server = ctx.socket(zmq.XPUB)
    server.setsockopt(zmq.XPUB_VERBOSE, 1)
    server.curve_server = True
    server.curve_publickey = own.public
    server.curve_secretkey = own.secret
    server.zap_domain = participant_domain(args.pose).encode()
    server.bind(args.bind)

    spies: list[zmq.Socket[Any]] = []
    for spec in args.peer:
        name, _, endpoint = spec.partition("=")
        curve = ctx.socket(zmq.SUB)
        curve.curve_serverkey = public[name]
        curve.curve_publickey = own.public
        curve.curve_secretkey = own.secret
        curve.subscribe(b"")
        curve.connect(endpoint)
        plain = ctx.socket(zmq.SUB)
        plain.subscribe(b"")
        plain.connect(endpoint)
        spies += [curve, plain]

    nodes = args.nodes.split(",")
    forged: list[wire.Message] = []
    for seq, node in enumerate(nodes, start=1):
        forged.append(
            wire.Trigger(args.mission, args.pose, args.target, "n0", node, (), "failed", seq=seq)
        )
    forged.append(wire.Abort(args.mission, args.pose, "forged abort", seq=1))
    forged.append(wire.Heartbeat(args.mission, args.pose, {args.target: len(nodes)}, 1))

    poller = zmq.Poller()
    for sock in [server, *spies]:
        poller.register(sock, zmq.POLLIN)
    received = 0
    subscriptions = 0
    published = 0
    deadline = time.monotonic() + args.seconds
    while time.monotonic() < deadline and not (args.stop_file and args.stop_file.exists()):
        for msg in forged:
            server.send_multipart(wire.encode(msg))
            published += 1
        for sock, _ in poller.poll(100):  # the pace of the forgery, bounded by the deadline
            while True:
                try:
                    frames = sock.recv_multipart(zmq.NOBLOCK)
                except zmq.Again:
                    break
                if sock is server:
                    if frames and frames[0][:1] == b"\x01":
                        subscriptions += 1
                else:
                    received += 1
    args.out.write_text(
        json.dumps({"received": received, "subscriptions": subscriptions, "published": published})
    )
    for sock in [server, *spies]:
        sock.close(linger=0)
    auth.stop()
    ctx.term()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
