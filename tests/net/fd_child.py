"""A participant ``B`` in its own process, for the descriptor test (``test_net_descriptors``).

``python -m tests.net.fd_child KEYS BIND PEER_A COUNT OUT``: binds ``BIND`` with
B's fleet keys, connects to A, prints ``ready <soft limit>``, and writes one
file under ``OUT`` for each trigger from A (a node needs descriptors of its
own: logs, report, summary) and answers it with a trigger to A (over its own
Out-Bridge, the flooded side).  Exits 0 once it got ``COUNT`` triggers and A
acknowledged every answer, 1 on timeout.
"""

from __future__ import annotations

import resource
import sys
import threading
from pathlib import Path
from typing import Any

import zmq

from eamos.logs import close_logger, make_logger
from eamos.net import wire
from eamos.net.keys import FleetKeys
from eamos.net.link import Link

from .session_helpers import FAST, MISSION

WAIT_S = 120.0


def main(argv: list[str]) -> int:
    keys, bind, peer, count, out = argv
    out_dir = Path(out)
    log = make_logger(out_dir / "b.log", drone="B")
    ctx: zmq.Context[Any] = zmq.Context()
    got: set[int] = set()
    done = threading.Event()

    def on_message(msg: Any) -> None:
        if isinstance(msg, wire.Trigger):
            n = msg.iteration[0]
            (out_dir / f"trigger-{n}").write_text(f"{n}\n")
            got.add(n)
            link.send(wire.Trigger(MISSION, "B", "A", "echo", "b", (n,), "done"))
            if len(got) >= int(count):
                done.set()

    link = Link(
        ctx, "B", MISSION, bind, log, keys=FleetKeys.load(Path(keys) / "B", "B"), settings=FAST
    )
    try:
        link.connect({"A": peer}, (), on_message)
        print("ready", resource.getrlimit(resource.RLIMIT_NOFILE)[0], flush=True)
        ok = done.wait(WAIT_S) and link.flush(WAIT_S)
    finally:
        link.close()
        ctx.destroy(linger=0)
        close_logger(log)
    print("done" if ok else "timeout", len(got), flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
