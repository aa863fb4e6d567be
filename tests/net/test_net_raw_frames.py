"""send_message / recv_message: the frames of one message out and in, whole (pyzmq multipart)."""

from __future__ import annotations

import uuid

import pytest
import zmq

from eamos.net.sockets import recv_message, send_message


def test_messages_of_one_or_more_frames_arrive_whole_and_in_order() -> None:
    ctx = zmq.Context()
    address = f"inproc://raw-{uuid.uuid4().hex}"
    rx, tx = ctx.socket(zmq.PAIR), ctx.socket(zmq.PAIR)
    try:
        rx.bind(address)
        tx.connect(address)
        with pytest.raises(zmq.Again):
            recv_message(rx)  # nothing waits
        sent = [[b"to/D2", b"payload"], [b"one"], [b"a", b"", b"c" * 5000]]
        for frames in sent:
            send_message(tx, frames)
        assert rx.poll(10_000)
        assert [recv_message(rx) for _ in sent] == sent
        tx.send_multipart([b"x", b"y"])  # and pyzmq's own multipart reads the same
        assert rx.poll(10_000) and recv_message(rx) == [b"x", b"y"]
        with pytest.raises(TypeError):
            send_message(tx, ["not bytes"])  # type: ignore[list-item]
    finally:
        rx.close(linger=0)
        tx.close(linger=0)
        ctx.term()
