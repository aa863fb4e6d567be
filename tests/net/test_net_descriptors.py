"""Thousands of idle, unauthenticated TCP connections must not take a node's descriptors.

The node (``fd_child``, participant B) runs in its own process under a low
``RLIMIT_NOFILE``; the test floods its Out-Bridge with raw TCP connections
that never say a word, then sends it triggers over a CURVE link from A.  B must
get them all, still open files of its own, and answer each over its
Out-Bridge (the flooded side).
"""

from __future__ import annotations

import resource
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from eamos.logs import read_log
from eamos.net import wire
from eamos.net.descriptors import connection_budget, raise_descriptor_limit

from .link_helpers import WAIT_S, Inbox, free_port, network, trig

pytestmark = pytest.mark.timeout(240)
REPO = Path(__file__).resolve().parents[2]
FLOOD = 1500
TRIGGERS = 20


def limited(soft: int, hard: int) -> Any:
    def preexec() -> None:
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))

    return preexec


def flood(port: int, count: int) -> list[socket.socket]:
    """Open up to ``count`` idle TCP connections (refusals while B does not listen are fine)."""
    held: list[socket.socket] = []
    for _ in range(count):
        try:
            held.append(socket.create_connection(("127.0.0.1", port), timeout=2.0))
        except OSError:
            pass
    return held


@pytest.mark.parametrize(
    ("soft", "hard", "flooded"),
    [(256, 256, True), (256, 8192, False)],
    ids=["hard-limit-256-stops-listening", "soft-limit-raised"],
)
def test_idle_connections_do_not_exhaust_a_node(
    tmp_path: Path, soft: int, hard: int, flooded: bool
) -> None:
    if resource.getrlimit(resource.RLIMIT_NOFILE)[0] < FLOOD + 500:
        pytest.skip("this test process needs a descriptor limit above the flood")
    out = tmp_path / "b"
    out.mkdir()
    with network(tmp_path) as net:
        keys = net.keys(["A", "B"])
        port = free_port()
        net.endpoints["B"] = f"tcp://127.0.0.1:{port}"
        inbox = Inbox()
        a = net.link("A", ["B"], inbox, secure=True)
        endpoints = (net.endpoints["B"], net.endpoints["A"])
        child = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "tests.net.fd_child",
                str(keys),
                *endpoints,
                str(TRIGGERS),
                str(out),
            ],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=limited(soft, hard),
        )
        held: list[socket.socket] = []
        try:
            assert child.stdout is not None
            ready = child.stdout.readline().split()
            assert ready[:1] == ["ready"], child.stderr.read() if child.stderr else ""
            assert int(ready[1]) == hard  # raised to the hard limit
            held = flood(port, FLOOD)
            assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
            for n in range(TRIGGERS):
                a.send(trig("A", "B", n))
            # B answers each over its own (flooded) Out-Bridge.
            assert inbox.wait_type(wire.Trigger, TRIGGERS, timeout=180)
            stdout, stderr = child.communicate(timeout=180)
        finally:
            for s in held:
                s.close()
            if child.poll() is None:
                child.kill()
                child.wait()
    assert child.returncode == 0, (stdout, stderr)
    assert "Too many open files" not in stderr and "Traceback" not in stderr
    assert sorted(p.name for p in out.glob("trigger-*")) == sorted(
        f"trigger-{n}" for n in range(TRIGGERS)
    )
    events = read_log(out / "b.log")
    pauses = [e for e in events if e["event"] == "net.out.flooded"]
    assert bool(pauses) is flooded
    if flooded:
        assert pauses[0]["connections"] >= pauses[0]["budget"] and pauses[0]["level"] == "warning"
        assert any(e["event"] == "net.out.listening" for e in events)
    else:
        assert any(e["event"] == "net.descriptors.raised" for e in events)


def test_the_limit_is_raised_and_the_budget_keeps_a_reserve() -> None:
    soft = raise_descriptor_limit()
    assert soft == resource.getrlimit(resource.RLIMIT_NOFILE)[0]
    assert raise_descriptor_limit() == soft  # idempotent
    assert 16 <= connection_budget() < soft


def test_an_idle_unauthenticated_connection_is_closed(tmp_path: Path) -> None:
    """A TCP client that never completes its handshake is dropped after the handshake interval."""
    with network(tmp_path) as net:
        net.keys(["A", "B"])
        inbox = Inbox()
        net.link("B", ["A"], inbox, secure=True)
        a = net.link("A", ["B"], secure=True)
        port = int(net.endpoints["A"].rsplit(":", 1)[1])
        idle = socket.create_connection(("127.0.0.1", port), timeout=WAIT_S)
        try:
            # Three times HANDSHAKE_IVL_MS (5 s); libzmq's default (30 s) would fail.
            idle.settimeout(15.0)
            received = b""
            while chunk := idle.recv(4096):  # ZeroMQ's greeting, then the close
                received += chunk
            assert received.startswith(b"\xff")  # it was ZeroMQ that closed it
        finally:
            idle.close()
        # The fleet's own link was not disturbed.
        assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
        a.send(trig("A", "B", 0))
        assert inbox.wait_type(wire.Trigger, 1)
