"""Watch a monitor page over its websocket until the run's outcome word; print it as JSON.

``python -m tests.monitor.watch_page PORT`` (or ``-``: PORT on stdin) -- tests
run it where the monitor listens (inside a lab's operator network namespace,
whose 127.0.0.1 is not the test's).  Output:
``{"page": ..., "messages": N, "link_patches_running": N}``.
"""

from __future__ import annotations

import json
import sys

from websockets.sync.client import connect

from eamos.monitor.state import apply_patches

FINAL_WORDS = {"finished", "failed", "aborted", "timed out"}


def watch(port: int, timeout_s: float = 180) -> dict:
    """The page's state from the snapshot and patches until the outcome word."""
    messages = running = 0
    with connect(f"ws://127.0.0.1:{port}/ws", open_timeout=30) as ws:
        page = json.loads(ws.recv(timeout=timeout_s))["state"]
        messages += 1
        while page["mission"]["state"] not in FINAL_WORDS:
            msg = json.loads(ws.recv(timeout=timeout_s))
            messages += 1
            for patch in msg["patches"]:
                apply_patches(page, [patch])
                if patch["k"] == "link" and page["mission"]["state"] == "running":
                    running += 1
    return {"page": page, "messages": messages, "link_patches_running": running}


if __name__ == "__main__":
    # PORT, or "-": the first line of stdin (a watcher started ahead of the monitor is up,
    # its imports done, the moment the port is known).
    print(json.dumps(watch(int(sys.stdin.readline() if sys.argv[1] == "-" else sys.argv[1]))))
