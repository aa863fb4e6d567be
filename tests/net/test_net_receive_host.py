"""In-Bridges of one process read by one thread (:class:`~eamos.net.receive_host.ReceiveHost`).

Real bridges on loopback, as drones sharing a process have them: each bridge gets
its own peers' messages, in order; one bridge that leaves (closed, from its own
callback too) or whose sockets fail is the only one that stops; the others read on.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zmq

from eamos.logs import close_logger, make_logger, read_log
from eamos.net import InBridge, Message, OutBridge, Trigger, topic_to
from eamos.net import in_bridge as in_bridge_module
from eamos.net.receive_host import ReceiveHost

from .net_helpers import MISSION, WAIT_S, Bridges, Collector

pytestmark = pytest.mark.timeout(120)

GCS = topic_to("GCS")  # what the bridges here listen to


def trig(sender: str, dest: str, n: int) -> Trigger:
    return Trigger(MISSION, sender, dest, "a", "b", (n,), "done")


def _receive_threads(before: set[threading.Thread]) -> list[str]:
    """The receive threads started since ``before`` that still run."""
    new = set(threading.enumerate()) - before
    return sorted(t.name for t in new if t.name.startswith("eamos-inbridge"))


@pytest.fixture
def host(ctx: zmq.Context[Any]) -> Iterator[ReceiveHost]:
    receive = ReceiveHost(ctx)
    yield receive
    assert receive.stop()


def _pair(
    bridges: Bridges, name: str, host: ReceiveHost, **kw: Any
) -> tuple[OutBridge, InBridge, Collector]:
    """Peer ``name``'s Out-Bridge and an In-Bridge on ``host`` listening to it."""
    out = bridges.out()
    inbox = Collector()
    inb = bridges.inb({name: out.endpoint}, [GCS], inbox, host=host, **kw)
    assert out.wait_subscribed([GCS], WAIT_S)
    return out, inb, inbox


def _iterations(inbox: Collector) -> list[int]:
    return [m.iteration[0] for m in inbox.messages if isinstance(m, Trigger)]


def test_bridges_on_one_receive_thread_each_get_their_own_peers_messages(
    bridges: Bridges, host: ReceiveHost
) -> None:
    before = set(threading.enumerate())
    pairs = {name: _pair(bridges, name, host) for name in ("D1", "D2", "D3")}
    assert _receive_threads(before) == ["eamos-inbridges"]  # no thread per bridge
    for n in range(60):
        for name, (out, _, _) in pairs.items():
            assert out.send(trig(name, "GCS", n))
    for name, (_, _, inbox) in pairs.items():
        assert inbox.wait_count(60)
        assert _iterations(inbox) == list(range(60))
        assert {m.sender for m in inbox.messages} == {name}


def test_closing_one_bridge_leaves_the_others_reading(bridges: Bridges, host: ReceiveHost) -> None:
    out1, inb1, inbox1 = _pair(bridges, "D1", host)
    out2, inb2, inbox2 = _pair(bridges, "D2", host)
    inb1.close()
    assert inb1.wait_ended(0) and not inb1.alive  # close() returns once its sockets closed
    assert not inb1.add_subscription(topic_to("x"))
    for n in range(20):
        out1.send(trig("D1", "GCS", n))
        out2.send(trig("D2", "GCS", n))
    assert inbox2.wait_count(20) and _iterations(inbox2) == list(range(20))
    assert inbox1.messages == [] and inb2.alive and host.alive


def test_a_bridge_closing_itself_in_its_callback_stops_alone(
    bridges: Bridges, host: ReceiveHost
) -> None:
    holder: list[InBridge] = []
    seen: list[Message] = []

    def close_at_first(msg: Message) -> None:
        seen.append(msg)
        holder[0].close()  # on the shared thread: must neither deadlock nor stop it

    out1 = bridges.out()
    holder.append(bridges.inb({"D1": out1.endpoint}, [GCS], close_at_first, host=host))
    out2, _, inbox2 = _pair(bridges, "D2", host)
    assert out1.wait_subscribed([GCS], WAIT_S)
    for n in range(30):
        out1.send(trig("D1", "GCS", n))
    assert holder[0].wait_ended(WAIT_S)
    for n in range(30):
        out2.send(trig("D2", "GCS", n))
    assert inbox2.wait_count(30) and _iterations(inbox2) == list(range(30))
    assert len(seen) == 1  # nothing delivered after its close


def test_a_bridge_whose_sockets_fail_leaves_and_the_others_go_on(
    bridges: Bridges, host: ReceiveHost, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    log = make_logger(tmp_path / "d1.log", drone="GCS")
    out1, inb1, _ = _pair(bridges, "D1", host, log=log)
    out2, inb2, inbox2 = _pair(bridges, "D2", host)
    failing = set(inb1.sockets())
    read = in_bridge_module.read_batch

    def read_or_fail(sub: zmq.Socket[Any], limit: int = in_bridge_module.READ_BATCH) -> Any:
        # Where a socket's failure would arise: reading it, on the receive thread.
        if sub in failing:
            raise zmq.ZMQError(zmq.EFAULT)
        return read(sub, limit)

    monkeypatch.setattr(in_bridge_module, "read_batch", read_or_fail)
    out1.send(trig("D1", "GCS", 0))
    assert inb1.wait_ended(WAIT_S) and not inb1.alive
    for n in range(20):
        out2.send(trig("D2", "GCS", n))
    assert inbox2.wait_count(20) and inb2.alive and host.alive
    inb1.close()  # a bridge that left already closes at once
    close_logger(log)
    assert [e["event"] for e in read_log(tmp_path / "d1.log")].count("net.in.thread_error") == 1


def test_stopping_the_host_lets_every_bridge_go(ctx: zmq.Context[Any], bridges: Bridges) -> None:
    before = set(threading.enumerate())
    receive = ReceiveHost(ctx)
    pairs = [_pair(bridges, name, receive) for name in ("D1", "D2")]
    assert receive.stop()
    assert _receive_threads(before) == []
    for _, inb, _ in pairs:
        assert inb.wait_ended(0) and not inb.alive
        assert not inb.add_subscription(topic_to("x"))
    late = InBridge(ctx, {"D3": pairs[0][0].endpoint}, [GCS], Collector(), MISSION, host=receive)
    with pytest.raises(RuntimeError, match="ended"):
        late.start()
    assert late.wait_ended(0)  # its sockets were closed, not leaked
