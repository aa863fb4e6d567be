"""Links of one process ticked by one thread (:class:`~eamos.net.timers.TimerHost`).

Real links on loopback, as drones sharing a process have them: heartbeats,
retransmissions and liveness still run at each link's own deadlines, a tick that
raises on one link stops neither its timer nor the others', and closing a link ends
only its timer.
"""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from eamos.logs import close_logger, make_logger, read_log
from eamos.net import wire
from eamos.net.timers import TimerHost

from .link_helpers import WAIT_S, Inbox, Lossy, eventually, fail_one_tick, network, trig


def _link_threads(before: set[threading.Thread]) -> list[str]:
    """The link threads started since ``before`` that still run."""
    new = set(threading.enumerate()) - before
    return [t.name for t in new if t.name.startswith("eamos-link")]


def test_links_on_one_timer_thread_retransmit_what_is_lost(tmp_path: Path) -> None:
    before = set(threading.enumerate())
    host = TimerHost()
    try:
        with network(tmp_path) as net:
            inboxes = {n: Inbox() for n in ("B", "C")}
            for name, inbox in inboxes.items():
                net.link(name, ["A"], inbox, timers=host)
            a = net.link("A", ["B", "C"], timers=host)
            for dest in inboxes:
                assert a.wait_subscribed([wire.topic_to(dest)], WAIT_S)
            # One thread ticks all three links; none has a timer thread of its own.
            assert _link_threads(before) == ["eamos-link-timers"]
            lossy = Lossy(a, seed=5)
            lossy.drop = lossy.random(0.3, (wire.Trigger,))
            for n in range(40):
                for dest in inboxes:
                    assert a.send(trig("A", dest, n))
            for inbox in inboxes.values():
                assert inbox.wait_type(wire.Trigger, 40), len(inbox.items)
                assert [m.iteration for m in inbox.of(wire.Trigger)] == [(n,) for n in range(40)]
            assert lossy.dropped > 0 and a.retransmissions >= lossy.dropped  # only the timer
            assert a.flush(WAIT_S)
            # Heartbeats go on, each link at its own period.
            beats = a.session.counters.heartbeats_sent
            assert eventually(lambda: a.session.counters.heartbeats_sent >= beats + 3)
    finally:
        host.stop()


def test_a_failing_tick_stops_neither_its_links_timer_nor_the_others(tmp_path: Path) -> None:
    log_path = tmp_path / "a.log"
    log = make_logger(log_path, drone="A")
    host = TimerHost()
    try:
        with network(tmp_path) as net:
            b = net.link("B", ["A"], timers=host)
            a = net.link("A", ["B"], log=log, timers=host)
            assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
            fail_one_tick(a)
            assert eventually(lambda: a.timer_errors == 1)
            beats = {x.name: x.session.counters.heartbeats_sent for x in (a, b)}
            assert eventually(
                lambda: all(x.session.counters.heartbeats_sent >= beats[x.name] + 2 for x in (a, b))
            )
            assert a.stats()["timer_errors"] == 1 and b.timer_errors == 0
    finally:
        host.stop()
        close_logger(log)
    errors = [e for e in read_log(log_path) if e["event"] == "net.link.timer_error"]
    assert len(errors) == 1 and "a tick's bug" in errors[0]["error"]


def test_closing_one_link_ends_only_its_timer(tmp_path: Path) -> None:
    before = set(threading.enumerate())
    host = TimerHost()
    try:
        with network(tmp_path) as net:
            inbox = Inbox()
            b = net.link("B", ["A"], inbox, timers=host)
            a = net.link("A", ["B"], timers=host)
            assert a.wait_subscribed([wire.topic_to("B")], WAIT_S)
            a.close()  # returns once the host saw it closed (its goodbye went)
            assert inbox.wait(lambda items: any(getattr(m, "state", "") == "left" for m in items))
            beats = b.session.counters.heartbeats_sent
            assert eventually(lambda: b.session.counters.heartbeats_sent >= beats + 2)
    finally:
        host.stop()
    assert _link_threads(before) == []  # the host's thread ended with stop()


def test_a_link_with_a_clock_of_its_own_is_refused_by_a_shared_timer(tmp_path: Path) -> None:
    host = TimerHost()
    try:
        with network(tmp_path) as net, pytest.raises(ValueError, match="another clock"):
            net.link("A", ["B"], clock=lambda: 0.0, timers=host)
    finally:
        host.stop()
