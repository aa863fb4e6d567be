"""Caller runs: a thread that is not a worker runs the turn of the actor it mailed.

``tell_here`` is how the In-Bridge's receive thread hands a trigger to its node
without waking a worker.  Real threads and Pykka refs.  The dispatchers here have
one worker, so "the actor is idle" can be known without waiting on time: after an
ask to a second actor returns, the worker has finished the first one's turn.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import pykka
import pytest

from eamos.actors import dispatch
from eamos.actors.dispatch import Dispatcher, LazyMail, PooledActor, tell_here
from eamos.actors.executive import DeliverInterrupt, TriggerReceived
from eamos.actors.inbound import InRouter
from eamos.actors.logic.telemetry import telemetry_values
from eamos.actors.messages import Interrupt, RemoteTelemetry, RemoteTrigger
from eamos.logs import make_logger
from eamos.net import wire

from .test_dispatch import Hop, News, Recorder, _ring

WAIT_S = 30.0
HOST = threading.current_thread().name  # pytest runs the tests on this thread


class Turns(PooledActor):
    """Records (message, thread) per handled message; counts turns that overlapped.

    ``"block"`` waits for ``gate``; ``"boom"`` raises (the hook keeps the actor);
    a callable is called with the actor.
    """

    def __init__(
        self,
        dispatcher: Dispatcher,
        gate: threading.Event | None = None,
        blocked: threading.Event | None = None,
    ) -> None:
        super().__init__(dispatcher)
        self.gate = gate
        self.seen: list[tuple[Any, str]] = []
        self.failures: list[tuple[str, str]] = []
        self.inside = 0
        self.overlaps = 0
        self.blocked = blocked if blocked is not None else threading.Event()
        self.after: Any = None  # called after each message (set by a callable message)

    def on_receive(self, message: Any) -> Any:
        self.inside += 1
        self.overlaps += self.inside > 1
        try:
            if message == "boom":
                raise ValueError("boom")
            if message == "block" and self.gate is not None:
                self.blocked.set()
                self.gate.wait(WAIT_S)
            if callable(message):
                message(self)
            elif self.after is not None:
                self.after()
            self.seen.append((message, threading.current_thread().name))
            return len(self.seen)
        finally:
            self.inside -= 1

    def on_failure(self, exception_type: Any, exception_value: Any, traceback: Any) -> None:
        self.failures.append((repr(exception_value), threading.current_thread().name))

    def report(self) -> tuple[list[tuple[Any, str]], int]:
        return list(self.seen), self.overlaps


@pytest.fixture
def one() -> Iterator[Dispatcher]:
    d = Dispatcher(workers=1, name="host")
    yield d
    d.shutdown()


def _settle(dispatcher: Dispatcher, *refs: Any) -> None:
    """Return once every actor in ``refs`` is idle (one worker: see the module's docstring)."""
    for ref in refs:
        ref.ask("settle", timeout=WAIT_S)
    other = Recorder.start(dispatcher)
    other.ask("after", timeout=WAIT_S)
    other.stop(block=True, timeout=WAIT_S)


def test_an_idle_actor_runs_on_the_caller_before_tell_here_returns(one: Dispatcher) -> None:
    ref = Turns.start(one)
    _settle(one, ref)
    for i in range(3):
        tell_here(ref, i)  # no wait after it: the turn ran inside the call
    seen, overlaps = ref.proxy().report().get(timeout=WAIT_S)
    assert seen[1:] == [(0, HOST), (1, HOST), (2, HOST)]
    assert overlaps == 0
    ref.stop(block=True, timeout=WAIT_S)


def test_a_busy_actor_only_gets_the_mail_and_keeps_its_order(one: Dispatcher) -> None:
    gate, blocked = threading.Event(), threading.Event()
    ref = Turns.start(one, gate, blocked)
    ref.tell("block")
    assert blocked.wait(WAIT_S)
    tell_here(ref, "a")  # the actor is running on the worker: not run here
    tell_here(ref, "b")
    gate.set()
    assert ref.ask("last", timeout=WAIT_S) == 4
    seen, overlaps = ref.proxy().report().get(timeout=WAIT_S)
    assert [m for m, _ in seen] == ["block", "a", "b", "last"]
    assert HOST not in {t for _, t in seen}
    assert overlaps == 0
    ref.stop(block=True, timeout=WAIT_S)


def test_the_caller_and_the_workers_never_run_one_actor_at_once() -> None:
    """Many callers and ordinary mail at once: each sender's order kept, no overlap."""
    two = Dispatcher(workers=2, name="host-two")
    try:
        ref = Turns.start(two)
        start = threading.Barrier(3)

        def send(name: str, here: bool) -> None:
            start.wait(WAIT_S)
            for i in range(300):
                (tell_here if here else pykka.ActorRef.tell)(ref, (name, i))

        threads = [
            threading.Thread(target=send, args=(n, h)) for n, h in (("x", True), ("y", True))
        ]
        for thread in threads:
            thread.start()
        start.wait(WAIT_S)
        send_plain = [("z", i) for i in range(300)]
        for message in send_plain:
            ref.tell(message)
        for thread in threads:
            thread.join(WAIT_S)
        assert ref.ask("last", timeout=WAIT_S) == 901
        seen, overlaps = ref.proxy().report().get(timeout=WAIT_S)
        assert overlaps == 0
        for name in "xyz":
            assert [m for m, _ in seen if m[0] == name] == [(name, i) for i in range(300)]
        ref.stop(block=True, timeout=WAIT_S)
    finally:
        two.shutdown()


def test_a_chain_runs_on_the_caller_for_a_few_turns_then_on_a_worker(one: Dispatcher) -> None:
    done = threading.Event()
    log = Recorder.start(one)
    refs = _ring(one, 10, log, done)
    _settle(one, log, *refs)
    tell_here(refs[0], Hop(30))
    assert done.wait(WAIT_S)
    # The first turns ran here (the receive thread has more to read), the rest on the worker.
    ran_here = [r for r in refs if HOST in r.proxy().threads.get(timeout=WAIT_S)]
    assert len(ran_here) == dispatch._HOST_TURNS
    assert all(len(r.proxy().threads.get(timeout=WAIT_S)) >= 1 for r in refs)
    # The lazy news the caller's turns sent reached the log, in order, with the rest.
    seen = log.proxy().seen_so_far().get(timeout=WAIT_S)
    assert [n.text for n in seen if isinstance(n, News)] == [f"hop {i}" for i in range(30, -1, -1)]
    for ref in [*refs, log]:
        ref.stop(block=True, timeout=WAIT_S)


@dataclass(frozen=True)
class Note(LazyMail):
    text: str


def test_lazy_news_runs_on_the_caller_once_its_slot_is_empty(one: Dispatcher) -> None:
    log = Turns.start(one)
    ref = Turns.start(one)
    _settle(one, log, ref)
    tell_here(ref, lambda actor: log.tell(Note("news")))
    # Both turns ran inside the call, on this thread: the node's, then its news.
    log_seen, _ = log.proxy().report().get(timeout=WAIT_S)
    assert log_seen[1:] == [(Note("news"), HOST)]
    ref_seen, _ = ref.proxy().report().get(timeout=WAIT_S)
    assert ref_seen[1][1] == HOST
    for r in (ref, log):
        r.stop(block=True, timeout=WAIT_S)


def test_a_failing_turn_on_the_caller_goes_to_the_hook_and_the_actor_lives(
    one: Dispatcher,
) -> None:
    ref = Turns.start(one)
    _settle(one, ref)
    tell_here(ref, "boom")  # does not raise: the failure is the actor's
    assert ref.proxy().failures.get(timeout=WAIT_S) == [("ValueError('boom')", HOST)]
    assert ref.ask("alive", timeout=WAIT_S) == 2


def test_a_stopped_actor_refuses_and_a_stopped_dispatcher_runs_nothing_here() -> None:
    d = Dispatcher(workers=1, name="host-stop")
    gone = Turns.start(d)
    gone.stop(block=True, timeout=WAIT_S)
    with pytest.raises(pykka.ActorDeadError):
        tell_here(gone, "late")
    ref = Turns.start(d)
    _settle(d, ref)
    d.shutdown()
    ran = threading.Event()
    tell_here(ref, lambda actor: ran.set())  # only mailed: nothing runs on the caller
    assert not ran.is_set()  # (it would have run inside the call; no worker is left)


def test_a_plain_pykka_actor_just_gets_the_mail() -> None:
    got = threading.Event()

    class Plain(pykka.ThreadingActor):
        def on_receive(self, message: Any) -> Any:
            got.set()

    ref = Plain.start()
    try:
        tell_here(ref, "hello")
        assert got.wait(WAIT_S)
    finally:
        ref.stop()


def _router(node: Any, executive: Any, board: Any = None) -> InRouter:
    return InRouter(
        drone="D2",
        nodes={"n2": node},
        executive=executive,
        board=board,
        log=make_logger(None),
        abort=lambda reason: None,
        completed=threading.Event(),
        failure=lambda part, exc: None,
    )


def test_the_in_bridge_hands_an_interrupt_to_the_executive_on_its_own_thread(
    one: Dispatcher,
) -> None:
    executive = Turns.start(one)
    _settle(one, executive)
    _router(None, executive)(wire.Interrupt("m", "D1", "D2", "7", (1,), "all"))
    seen, _ = executive.proxy().report().get(timeout=WAIT_S)
    assert seen[-1] == (DeliverInterrupt(Interrupt(7, (1,), "all")), HOST)


def test_the_in_bridge_hands_a_telemetry_sample_to_the_board_on_its_own_thread(
    one: Dispatcher,
) -> None:
    # A ground station's board gets every drone's samples: a worker woken per sample
    # cost more than the board's turn.
    board = Turns.start(one)
    _settle(one, board)
    sample = wire.TelemetrySample(
        "m", "D1", 1.0, 1.0, 2.0, 3.0, 47.0, 8.0, 500.0, 90.0, True, False
    )
    _router(None, None, board)(sample)
    seen, _ = board.proxy().report().get(timeout=WAIT_S)
    assert seen[-1] == (RemoteTelemetry("D1", telemetry_values(sample)), HOST)


def test_the_in_bridge_counts_a_trigger_before_the_node_turn_it_runs(one: Dispatcher) -> None:
    """The count is in the executive's inbox before the node's turn can make the drone
    resolve (and a report ask for the count), and the turn runs on the receive thread."""
    executive = Recorder.start(one)
    node = Turns.start(one)
    _settle(one, executive, node)
    router = _router(node, executive)
    # The node's turn tells the executive (as a node resolving the drone would).
    node.ask(lambda actor: setattr(actor, "after", lambda: executive.tell("resolved")))
    _settle(one)
    router(wire.Trigger("m", "D1", "D2", "n1", "n2", (), "done"))
    seen, _ = node.proxy().report().get(timeout=WAIT_S)
    assert seen[-1] == (RemoteTrigger("n1", "n2", (), "done", "D1"), HOST)
    got = executive.proxy().seen_so_far().get(timeout=WAIT_S)
    assert got[1:] == [TriggerReceived("D1"), "resolved"]
