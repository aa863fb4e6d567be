"""The operator's commands, part by part: what a resume issues, what the desk takes, and
the uniform space over a real simulated vehicle (pause stops a PauseFor's clock; a
release stops every command until a resume)."""

from __future__ import annotations

import json
import queue
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from eamos.actors.operator import remaining_command
from eamos.actors.uniform_api import ActionFinished, RunAction, UniformSpace
from eamos.ground.operator import (
    OperatorDesk,
    OperatorError,
    PauseClock,
    parse_request,
    send_command,
)
from eamos.ground.station import command_refusal
from eamos.hal.sim import SimAdapter, SimSettings
from eamos.logs import make_logger
from eamos.program.uniform import FlyBy, FlyToXYZ, Hold, Land, PauseFor, Takeoff


def test_a_relative_move_resumes_to_its_original_target() -> None:
    assert remaining_command(FlyBy("X", 5.0), 1.2, (1.0, 2.0, 3.0)) == FlyToXYZ(6.0, 2.0, 3.0)
    assert remaining_command(FlyBy("Z", -1.0), 0.0, (0.0, 0.0, 3.0)) == FlyToXYZ(0.0, 0.0, 2.0)


def test_a_timed_wait_resumes_for_what_it_had_left() -> None:
    assert remaining_command(PauseFor(10.0), 3.5, None) == PauseFor(6.5)
    assert remaining_command(Hold(2.0), 5.0, None) == Hold(0.0)


def test_absolute_moves_resume_as_they_were() -> None:
    assert remaining_command(Takeoff(2.0), 1.0, (0.0, 0.0, 1.0)) == Takeoff(2.0)
    assert remaining_command(Land(), 1.0, None) == Land()


def test_commands_are_checked_against_the_mission() -> None:
    drones = ["Drone1", "Drone2"]
    assert command_refusal("pause", "", drones) == ""
    assert command_refusal("land", "Drone2", drones) == ""
    assert "not a mission command" in command_refusal("land", "", drones)
    assert "no drone 'Drone9'" in command_refusal("hold", "Drone9", drones)
    assert "not a drone command" in command_refusal("pause", "Drone1", drones)


@pytest.mark.parametrize(
    ("data", "why"),
    [
        (b"not json\n", "not a JSON line"),
        (b"[1, 2]\n", "not a JSON object"),
        (b'{"command": 3}\n', "short strings"),
        (b"[" * 200_000 + b"\n", "over 4096 bytes"),
    ],
)
def test_the_desk_refuses_what_is_not_a_request(data: bytes, why: str) -> None:
    request, reason = parse_request(data)
    assert request is None and why in reason


def test_the_desk_answers_over_its_socket(tmp_path: Path) -> None:
    got: list[tuple[str, str, str]] = []

    def handle(command: str, drone: str, origin: str) -> str:
        got.append((command, drone, origin))
        return "" if command == "pause" else "refused here"

    desk = OperatorDesk(tmp_path, handle)
    assert desk.open() == ""
    try:
        assert (tmp_path / "operator.sock").stat().st_mode & 0o077 == 0  # owner only
        send_command(tmp_path, "pause", "", "cli user test")
        with pytest.raises(OperatorError, match="refused here"):
            send_command(tmp_path, "land", "Drone1", "cli user test")
        # A client that sends junk gets an answer, and the desk goes on.
        with socket.socket(socket.AF_UNIX) as sock:
            sock.connect(str(tmp_path / "operator.sock"))
            sock.sendall(b"junk\n")
            assert json.loads(sock.recv(4096)) == {
                "ok": False,
                "error": "the request is not a JSON line",
            }
        send_command(tmp_path, "pause", "", "cli user test")
    finally:
        desk.close()
    pause, land = ("pause", "", "cli user test"), ("land", "Drone1", "cli user test")
    assert got == [pause, land, pause]
    assert not (tmp_path / "operator.sock").exists()
    with pytest.raises(OperatorError, match="no ground station runs"):
        send_command(tmp_path, "pause", "", "cli user test")


class Replies:
    def __init__(self) -> None:
        self.q: queue.Queue[ActionFinished] = queue.Queue()

    def tell(self, message: ActionFinished) -> None:
        self.q.put(message)


SPEEDUP = 4.0


@pytest.fixture
def space() -> Iterator[UniformSpace]:
    adapter = SimAdapter("D1", SimSettings(speedup=SPEEDUP))
    adapter.start(lambda sample: None)
    yield UniformSpace(adapter, make_logger(None))
    adapter.close()


def test_a_pause_stops_a_pausefor_clock(space: UniformSpace) -> None:
    replies = Replies()
    adapter = space.adapter
    assert isinstance(adapter, SimAdapter)
    t0 = adapter.sim_time_s
    assert space.run(RunAction("p", "PauseFor", (4.0,), replies)) is None
    time.sleep(1.0 / SPEEDUP)  # about 1 simulated second of the PauseFor
    space.operate("pause")
    paused_at = adapter.sim_time_s
    time.sleep(6.0 / SPEEDUP)  # 6 simulated seconds paused: longer than the PauseFor
    assert replies.q.empty()  # suspended, not answered
    resumed_at = adapter.sim_time_s
    space.operate("resume")
    done = replies.q.get(timeout=30)
    assert done.result.status == "ok"
    ended_at = adapter.sim_time_s
    # What it ran before the pause and after the resume makes its 4 s (the braces: the
    # pacing of a loaded machine).
    ran = (paused_at - t0) + (ended_at - resumed_at)
    assert 3.8 <= ran <= 4.6, (paused_at - t0, ended_at - resumed_at)


def test_a_release_stops_every_command_until_resume(space: UniformSpace) -> None:
    replies = Replies()
    space.operate("release")
    assert space.released
    refused = space.run(RunAction("a", "Arm", (), replies))
    assert refused is not None and refused.result.status == "failed"
    assert "RELEASED by the operator" in refused.result.reason
    space.operate("resume")
    assert not space.released


def test_the_pause_clock_counts_only_paused_time() -> None:
    pauses = PauseClock()
    assert pauses.paused_s(5.0) == 0.0
    pauses.pause(10.0)
    pauses.pause(11.0)  # again: the first one counts
    assert pauses.paused_s(14.0) == 4.0
    pauses.resume(15.0)
    pauses.resume(16.0)
    assert pauses.paused_s(30.0) == 5.0


def test_a_suspended_action_cancelled_while_paused_ends_at_once(space: UniformSpace) -> None:
    """A Whenever, a Try or a Do may cancel an action the operator's pause suspended (or
    one that waits for the resume): its node gets its answer then, not never."""
    replies = Replies()
    assert space.run(RunAction("running", "PauseFor", (30.0,), replies)) is None
    space.operate("pause")
    assert space.run(RunAction("queued", "PauseFor", (30.0,), replies)) is None
    space.cancel("running")
    space.cancel("queued")
    got = {r.token: r.result.status for r in (replies.q.get(timeout=5), replies.q.get(timeout=5))}
    assert got == {"running": "cancelled", "queued": "cancelled"}
    space.operate("resume")  # nothing left to issue
    assert replies.q.empty()
