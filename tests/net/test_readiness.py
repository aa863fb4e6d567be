"""SocketWatch: the readable sockets of many, through their descriptors (real inproc sockets)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest
import zmq

from eamos.net.readiness import SocketWatch


@pytest.fixture
def pairs() -> Iterator[list[tuple[zmq.Socket[Any], zmq.Socket[Any]]]]:
    context = zmq.Context()
    made: list[tuple[zmq.Socket[Any], zmq.Socket[Any]]] = []
    for i in range(50):
        rx, tx = context.socket(zmq.PAIR), context.socket(zmq.PAIR)
        rx.bind(f"inproc://watch-{i}")
        tx.connect(f"inproc://watch-{i}")
        made.append((rx, tx))
    yield made
    for rx, tx in made:
        rx.close(linger=0)
        tx.close(linger=0)
    context.term()


def test_what_was_queued_before_the_watch_is_found(pairs: list[Any]) -> None:
    rx, tx = pairs[7]
    tx.send(b"early")
    watch = SocketWatch()
    for r, _ in pairs:
        watch.add(r)
    assert watch.wait(5.0) == {rx}
    assert rx.recv() == b"early"
    assert watch.wait(0.05) == set()  # drained: nothing more, the wait timed out
    watch.close()


def test_only_the_ready_socket_of_many_is_returned(pairs: list[Any]) -> None:
    watch = SocketWatch()
    for r, _ in pairs:
        watch.add(r)
    assert watch.wait(0) == set()  # the first look at all of them: none readable
    rx, tx = pairs[31]
    # Sent from another thread while the watch blocks: the descriptor wakes it.
    sender = threading.Timer(0.05, lambda: tx.send(b"late"))
    sender.start()
    assert watch.wait(10.0) == {rx}
    sender.join()
    assert rx.recv() == b"late"
    watch.close()


def test_a_socket_left_readable_is_returned_again_without_a_new_signal(pairs: list[Any]) -> None:
    rx, tx = pairs[0]
    watch = SocketWatch()
    watch.add(rx)
    for n in range(3):
        tx.send(b"%d" % n)
    assert watch.wait(5.0) == {rx}
    assert rx.recv() == b"0"  # one read of three: the reading consumed the signal
    watch.again(rx)
    assert watch.wait(5.0) == {rx}
    assert [rx.recv(), rx.recv()] == [b"1", b"2"]
    assert watch.wait(0.05) == set()
    watch.close()
