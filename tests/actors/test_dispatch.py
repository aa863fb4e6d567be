"""The M:N dispatcher keeps Pykka's actor contract, with an explicit failure hook.

Real threads and real Pykka refs and futures; every wait is on a future or an event.
"""

from __future__ import annotations

import re
import threading
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from types import TracebackType
from typing import Any

import pykka
import pytest

from eamos.actors.dispatch import Dispatcher, LazyMail, PooledActor, RidesAlong
from eamos.actors.pykka_seam import PYKKA_TESTED, ActorExit

WAIT_S = 30.0


class Recorder(PooledActor):
    """Records what it receives; ``"boom"`` raises, ``"exit"`` raises SystemExit."""

    def __init__(self, dispatcher: Dispatcher, keep_alive: bool | None = None) -> None:
        super().__init__(dispatcher)
        self.seen: list[Any] = []
        self.failures: list[str] = []
        self.keep_alive = keep_alive  # None: Pykka's default hook
        self.stopped = threading.Event()

    def on_receive(self, message: Any) -> Any:
        if message == "boom":
            raise ValueError("boom")
        if message == "exit":
            raise SystemExit(3)
        if message == "interrupt":
            raise KeyboardInterrupt
        self.seen.append(message)
        return len(self.seen)

    def on_failure(
        self,
        exception_type: type[BaseException] | None,
        exception_value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if self.keep_alive is None:
            super().on_failure(exception_type, exception_value, traceback)
            return
        self.failures.append(repr(exception_value))
        if not self.keep_alive:
            raise RuntimeError("the hook gives up")

    def on_stop(self) -> None:
        self.stopped.set()

    def seen_so_far(self) -> list[Any]:
        return list(self.seen)


@pytest.fixture
def dispatcher() -> Iterator[Dispatcher]:
    d = Dispatcher(workers=2, name="test")
    yield d
    d.shutdown()


def test_the_installed_pykka_is_the_pinned_and_tested_range() -> None:
    """pyproject.toml's pin, the seam's PYKKA_TESTED and the installed Pykka agree."""
    pyproject = Path(__file__).parents[2] / "pyproject.toml"
    deps = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]["dependencies"]
    (pin,) = [d for d in deps if d.startswith("pykka")]
    low, high = PYKKA_TESTED
    assert re.sub(r"\s", "", pin) == f"pykka>={low[0]}.{low[1]},<{high[0]}.{high[1]}"
    installed = tuple(int(p) for p in metadata.version("pykka").split(".")[:2])
    assert low <= installed < high


def test_messages_are_handled_in_order_and_asks_are_answered(dispatcher: Dispatcher) -> None:
    refs = [Recorder.start(dispatcher) for _ in range(20)]
    for i in range(200):
        for ref in refs:
            ref.tell(i)
    for ref in refs:
        assert ref.ask("last", timeout=WAIT_S) == 201
        assert ref.proxy().seen_so_far().get(timeout=WAIT_S) == [*range(200), "last"]
        assert ref.stop(block=True, timeout=WAIT_S) is True
        assert not ref.is_alive()
    with pytest.raises(pykka.ActorDeadError):
        refs[0].tell("late")


def test_an_exception_answers_the_asker_and_the_actor_lives(dispatcher: Dispatcher) -> None:
    ref = Recorder.start(dispatcher)
    with pytest.raises(ValueError, match="boom"):
        ref.ask("boom", timeout=WAIT_S)
    assert ref.ask("after", timeout=WAIT_S) == 1
    ref.stop(block=True, timeout=WAIT_S)


def test_the_failure_hook_keeps_the_actor_alive(dispatcher: Dispatcher) -> None:
    ref = Recorder.start(dispatcher, keep_alive=True)
    ref.tell("boom")
    assert ref.ask("after", timeout=WAIT_S) == 1
    assert ref.proxy().failures.get(timeout=WAIT_S) == ["ValueError('boom')"]
    ref.stop(block=True, timeout=WAIT_S)


def test_without_a_hook_a_failure_stops_the_actor_as_in_pykka(
    dispatcher: Dispatcher, caplog: pytest.LogCaptureFixture
) -> None:
    ref = Recorder.start(dispatcher)
    ref.tell("boom")
    with pytest.raises(pykka.ActorDeadError):
        ref.ask("after", timeout=WAIT_S)
    assert not ref.is_alive()
    logged = [r for r in caplog.records if r.exc_info and "boom" in str(r.exc_info[1])]
    assert len(logged) == 1  # once, with its traceback


def test_a_hook_that_raises_stops_the_actor(dispatcher: Dispatcher) -> None:
    ref = Recorder.start(dispatcher, keep_alive=False)
    ref.tell("boom")
    with pytest.raises(pykka.ActorDeadError):
        ref.ask("after", timeout=WAIT_S)


class Gated(PooledActor):
    """Handles a message only once the event it is given is set (the actor is busy)."""

    def on_receive(self, message: Any) -> Any:
        if isinstance(message, threading.Event):
            message.wait(WAIT_S)
        return None


def test_a_stopped_actor_is_unregistered_and_answers_late_mail_as_pykka_does(
    dispatcher: Dispatcher,
) -> None:
    ref = Gated.start(dispatcher)
    assert pykka.ActorRegistry.get_by_urn(ref.actor_urn) is ref
    gate = threading.Event()
    ref.tell(gate)  # busy: what follows waits in its inbox
    first, second = ref.stop(block=False), ref.stop(block=False)
    late = ref.ask("late", block=False)
    gate.set()
    # The first stop stops it; the second (Pykka's stop message, seen after the actor
    # stopped) is answered as stopped too, and other mail with ActorDeadError.
    assert first.get(timeout=WAIT_S) is True
    assert second.get(timeout=WAIT_S) is True
    with pytest.raises(pykka.ActorDeadError):
        late.get(timeout=WAIT_S)
    assert pykka.ActorRegistry.get_by_urn(ref.actor_urn) is None


def test_a_failure_unregisters_the_actor(dispatcher: Dispatcher) -> None:
    ref = Recorder.start(dispatcher)
    ref.tell("boom")
    ref.actor_stopped.wait(WAIT_S)
    assert pykka.ActorRegistry.get_by_urn(ref.actor_urn) is None


EXITS = pytest.mark.parametrize("message", ["exit", "interrupt"])


@EXITS
def test_a_base_exception_stops_the_actors_of_its_dispatcher_only(
    dispatcher: Dispatcher, message: str, caplog: pytest.LogCaptureFixture
) -> None:
    """Pykka stops every actor of the process; here only those of the dispatcher."""
    one, other = Recorder.start(dispatcher), Recorder.start(dispatcher)
    elsewhere = Dispatcher(workers=1, name="test-elsewhere")
    try:
        neighbour = Recorder.start(elsewhere)
        threaded = pykka.ThreadingActor.start()
        one.tell(message)
        for ref in (one, other):
            ref.actor_stopped.wait(WAIT_S)
            with pytest.raises(pykka.ActorDeadError):
                ref.ask("after", timeout=WAIT_S)
        # Another dispatcher's actors (another drone's) and Pykka's own go on.
        assert neighbour.ask("after", timeout=WAIT_S) == 1
        assert threaded.is_alive()
        threaded.stop()
        neighbour.stop(block=True, timeout=WAIT_S)
    finally:
        elsewhere.shutdown()
    # The exception is logged once, with its traceback.
    expected = SystemExit if message == "exit" else KeyboardInterrupt
    logged = [r for r in caplog.records if r.exc_info and r.exc_info[0] is expected]
    assert len(logged) == 1


@EXITS
def test_a_base_exception_goes_to_on_failure_then_to_the_dispatchers_exit_hook(
    message: str,
) -> None:
    told: list[tuple[Any, BaseException]] = []
    hooked = Dispatcher(workers=2, name="test-hook", on_exit=lambda a, e: told.append((a, e)))
    try:
        one = Recorder.start(hooked, keep_alive=True)
        other = Recorder.start(hooked)
        one.tell(message)
        # on_failure kept the actor alive; nothing else was stopped.
        assert one.ask("after", timeout=WAIT_S) == 1
        failures = one.proxy().failures.get(timeout=WAIT_S)
        assert failures == [repr(SystemExit(3)) if message == "exit" else "KeyboardInterrupt()"]
        assert other.ask("after", timeout=WAIT_S) == 1
        ((actor, exc),) = told
        assert actor.actor_ref == one
        assert isinstance(exc, SystemExit if message == "exit" else KeyboardInterrupt)
        for ref in (one, other):
            ref.stop(block=True, timeout=WAIT_S)
    finally:
        hooked.shutdown()


@EXITS
def test_an_ask_whose_handler_exits_is_answered_with_an_ordinary_exception(
    dispatcher: Dispatcher, message: str
) -> None:
    """Pykka leaves the asker waiting; a SystemExit must not cross into the asker's thread.

    The exception still reaches the dispatcher's scope (here: its actors stop)."""
    expected = SystemExit if message == "exit" else KeyboardInterrupt
    ref = Recorder.start(dispatcher)
    with pytest.raises(ActorExit) as caught:
        ref.ask(message, timeout=WAIT_S)
    assert isinstance(caught.value.__cause__, expected)
    assert ref.actor_stopped.wait(WAIT_S)


class ExitsOnStart(PooledActor):
    def on_start(self) -> None:
        raise SystemExit(4)


def test_an_actor_whose_on_start_exits_is_stopped_and_the_hook_told() -> None:
    told: list[BaseException] = []
    hooked = Dispatcher(workers=1, name="test-start", on_exit=lambda a, e: told.append(e))
    try:
        ref = ExitsOnStart.start(hooked)
        with pytest.raises(pykka.ActorDeadError):
            ref.ask("hello", timeout=WAIT_S)
        assert [repr(e) for e in told] == ["SystemExit(4)"]
        assert Recorder.start(hooked).ask("x", timeout=WAIT_S) == 1  # the workers live on
    finally:
        hooked.shutdown()


class FailsToStart(PooledActor):
    def on_start(self) -> None:
        raise RuntimeError("cannot start")


def test_an_actor_that_fails_to_start_is_stopped(dispatcher: Dispatcher) -> None:
    ref = FailsToStart.start(dispatcher)
    with pytest.raises(pykka.ActorDeadError):
        ref.ask("hello", timeout=WAIT_S)
    # The workers survive: other actors still run.
    assert Recorder.start(dispatcher).ask("x", timeout=WAIT_S) == 1


@dataclass(frozen=True)
class Hop:
    left: int


@dataclass(frozen=True)
class News(LazyMail):
    text: str


class Relay(PooledActor):
    """Passes a Hop on to ``nxt`` until it reaches 0; records the threads that ran it."""

    def __init__(self, dispatcher: Dispatcher, log: Any, done: threading.Event) -> None:
        super().__init__(dispatcher)
        self.nxt: Any = None
        self.log = log  # an actor ref: gets News (lazy) at each hop, or None
        self.done = done
        self.threads: set[str] = set()

    def on_receive(self, message: Any) -> Any:
        if isinstance(message, Hop):
            self.threads.add(threading.current_thread().name)
            if self.log is not None:
                self.log.tell(News(f"hop {message.left}"))
            if message.left == 0:
                self.done.set()
            else:
                self.nxt.tell(Hop(message.left - 1))
        elif callable(message):
            message(self)
        return None


def _ring(dispatcher: Dispatcher, size: int, log: Any, done: threading.Event) -> list[Any]:
    refs = [Relay.start(dispatcher, log, done) for _ in range(size)]
    for ref, nxt in zip(refs, refs[1:] + refs[:1], strict=True):
        ref.proxy().nxt = nxt
    return refs


def test_a_chain_of_tells_runs_on_one_worker_and_lazy_news_arrives_in_order(
    dispatcher: Dispatcher,
) -> None:
    """The slot: a node's trigger wakes no other worker; LazyMail waits for a free moment."""
    done = threading.Event()
    log = Recorder.start(dispatcher)
    refs = _ring(dispatcher, 10, log, done)
    refs[0].tell(Hop(500))
    assert done.wait(WAIT_S)
    threads = set().union(*(r.proxy().threads.get(timeout=WAIT_S) for r in refs))
    assert len(threads) == 1, threads
    # Every piece of news arrives, in order, though it woke nobody.
    texts = [n.text for n in log.proxy().seen_so_far().get(timeout=WAIT_S)]
    assert texts == [f"hop {i}" for i in range(500, -1, -1)]
    for ref in [*refs, log]:
        ref.stop(block=True, timeout=WAIT_S)


def test_a_long_chain_does_not_starve_other_actors_on_one_worker() -> None:
    one = Dispatcher(workers=1, name="test-one")
    try:
        done = threading.Event()
        refs = _ring(one, 2, None, done)
        refs[0].tell(Hop(10**9))  # ping-pong for as long as the test lets it
        other = Recorder.start(one)
        assert other.ask("served", timeout=WAIT_S) == 1
        stop = threading.Event()
        # Ends the ping-pong: the next hop is dropped.
        refs[0].tell(lambda relay: setattr(relay, "nxt", _Drop(stop)))
        refs[1].tell(lambda relay: setattr(relay, "nxt", _Drop(stop)))
        assert stop.wait(WAIT_S)
        for ref in [*refs, other]:
            ref.stop(block=True, timeout=WAIT_S)
    finally:
        one.shutdown()


class _Drop:
    def __init__(self, stop: threading.Event) -> None:
        self.stop = stop

    def tell(self, message: Any) -> None:
        self.stop.set()


@dataclass(frozen=True)
class Count(RidesAlong):
    n: int


class Counter(Recorder):
    """Sets ``counted`` when it handles a :class:`Count`."""

    def __init__(self, dispatcher: Dispatcher) -> None:
        super().__init__(dispatcher)
        self.counted = threading.Event()

    def on_receive(self, message: Any) -> Any:
        if isinstance(message, Count):
            self.counted.set()
        return super().on_receive(message)


def test_mail_that_rides_along_wakes_nobody_and_comes_before_the_next_mail(
    dispatcher: Dispatcher,
) -> None:
    ref = Counter.start(dispatcher)
    assert ref.ask("started", timeout=WAIT_S) == 1
    counted = ref.proxy().counted.get(timeout=WAIT_S)
    ref.tell(Count(1))
    ref.tell(Count(2))
    # Nobody was woken for them: a bounded wait for what must not happen.
    assert not counted.wait(0.3)
    # The next mail (here an ask: whoever reads a count asks) comes after them.
    assert ref.ask("read", timeout=WAIT_S) == 4
    assert counted.is_set()
    assert ref.proxy().seen_so_far().get(timeout=WAIT_S) == ["started", Count(1), Count(2), "read"]
    ref.stop(block=True, timeout=WAIT_S)
