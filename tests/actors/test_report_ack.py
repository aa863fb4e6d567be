"""A drone offers its final report for as long as the ground station waits for reports.

Real links on loopback; the network "loses" what the drone sends for a while
(:class:`~tests.net.link_helpers.Lossy`, what a connection cut by a lossy network
does to PUB/SUB traffic).  Under 30 % loss on every host a connection can stay down
for longer than the drone's old 10 s bound, and the ground station then had no report.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

from eamos.actors.drone import REPORT_ACK_STOPPED_S, REPORT_ACK_TIMEOUT_S, report_acknowledged
from eamos.ground.flight import REPORT_WAIT_OK_S
from eamos.net import wire
from eamos.net.reports import report_messages
from eamos.program.uniform import GROUND_STATION
from tests.net.link_helpers import MISSION, WAIT_S, Inbox, Lossy, network


def _send_report(cut: Lossy, lost_for_s: float) -> None:
    until = time.monotonic() + lost_for_s
    cut.drop = lambda m: time.monotonic() < until
    for msg in report_messages(MISSION, "D1", {"ok": True}):
        assert cut.link.send(msg)


def test_a_report_lost_longer_than_a_stopped_drone_waits_still_arrives(tmp_path: Path) -> None:
    assert REPORT_ACK_TIMEOUT_S == REPORT_WAIT_OK_S  # as long as the ground station waits
    with network(tmp_path) as net:
        inbox = Inbox()
        net.link(GROUND_STATION, ["D1"], inbox)
        drone = net.link("D1", [GROUND_STATION])
        assert drone.wait_subscribed([wire.topic_to(GROUND_STATION)], WAIT_S)
        cut = Lossy(drone)
        _send_report(cut, REPORT_ACK_STOPPED_S + 2.0)
        notices: list[str] = []
        began = time.monotonic()
        assert report_acknowledged(drone, threading.Event(), notices.append)
        waited = time.monotonic() - began
        assert REPORT_ACK_STOPPED_S < waited < REPORT_ACK_TIMEOUT_S, waited
        assert inbox.wait_type(wire.Report), inbox.items
        assert cut.dropped > 0
        # The operator was told once that the drone still waits, and for how long.
        assert len(notices) == 1 and f"{REPORT_ACK_TIMEOUT_S:g} s" in notices[0], notices


def test_a_stopped_drone_offers_its_report_for_the_shorter_time(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        net.link(GROUND_STATION, ["D1"])
        drone = net.link("D1", [GROUND_STATION])
        assert drone.wait_subscribed([wire.topic_to(GROUND_STATION)], WAIT_S)
        cut = Lossy(drone)
        _send_report(cut, REPORT_ACK_TIMEOUT_S * 2)
        stop = threading.Event()
        stop.set()  # a signal stopped the node
        began = time.monotonic()
        assert not report_acknowledged(drone, stop)
        waited = time.monotonic() - began
        assert REPORT_ACK_STOPPED_S <= waited < REPORT_ACK_STOPPED_S + 5.0, waited


def test_a_ground_station_that_left_is_not_waited_for(tmp_path: Path) -> None:
    with network(tmp_path) as net:
        gcs = net.link(GROUND_STATION, ["D1"])
        drone = net.link("D1", [GROUND_STATION])
        assert drone.wait_subscribed([wire.topic_to(GROUND_STATION)], WAIT_S)
        assert gcs.wait_subscribed([wire.topic_to("D1")], WAIT_S)
        cut = Lossy(drone)
        _send_report(cut, REPORT_ACK_TIMEOUT_S * 2)
        gcs.close()  # its goodbye reaches the drone
        began = time.monotonic()
        assert report_acknowledged(drone, threading.Event())
        assert time.monotonic() - began < REPORT_ACK_STOPPED_S
