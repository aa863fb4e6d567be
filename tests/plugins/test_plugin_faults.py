"""A plugin cannot freeze a vehicle: whatever its "sim" implementation does, the action fails.

An implementation that raises anything (``SystemExit`` and ``KeyboardInterrupt`` too) fails
its action; one that sleeps or spins fails it at its deadline (``plugin_deadline_s``), its
thread abandoned.  The simulator never waits for a plugin in real time: it flies on, and
the vehicle can land and disarm at any moment.  In virtual time (``eamos check``) the
step that starts the action waits for the outcome, at most the deadline.

Real threads and a real simulator; the implementations live in this module and are named
by string, as an entry point names them.  A hanging implementation waits on (or spins
until) an event the fixture sets at the end, so no thread outlives the test.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from eamos.hal.api import ActionResult
from eamos.hal.sim.adapter import SimAdapter
from eamos.hal.sim.core import SIM_DT_S, SimCore
from eamos.hal.sim.plugin_api import SimOutcome, SimView
from eamos.hal.sim.settings import SimSettings
from eamos.logs import close_logger, make_logger, read_log
from eamos.program.plugins import ActionPlugin, PluginRegistry
from eamos.program.uniform import PluginAction, Takeoff, decode_command
from tests.hal.hal_helpers import WAIT_S, Done, TelemetrySink, do

pytestmark = pytest.mark.timeout(300)

#: Short, for the tests; the default is PLUGIN_DEADLINE_S.
DEADLINE_S = 1.0
#: What "at once" means on a loaded 2-core machine.
PROMPT_S = 10.0

_release = threading.Event()  # set by the fixture: every hanging implementation returns
_calls: list[str] = []


def _exits(view: SimView, command: PluginAction) -> SimOutcome:
    _calls.append("Quit")
    raise SystemExit(3)


def _interrupts(view: SimView, command: PluginAction) -> SimOutcome:
    _calls.append("CtrlC")
    raise KeyboardInterrupt


def _stalls(view: SimView, command: PluginAction) -> SimOutcome:
    _calls.append("Stall")
    _release.wait()
    return SimOutcome()


def _spins(view: SimView, command: PluginAction) -> SimOutcome:
    _calls.append("Spin")
    release = _release
    while not release.is_set():
        pass
    return SimOutcome()


def _steps(view: SimView, command: PluginAction) -> SimOutcome:
    return SimOutcome(duration_s=0.4, payload={"steps": view.payload.get("steps", 0.0) + 1})


def _bad_log(view: SimView, command: PluginAction) -> SimOutcome:
    return SimOutcome(log={"action": "mine", "handle": 3})


def _plugin(name: str, function: str) -> ActionPlugin:
    return ActionPlugin(name, (), name, {"sim": f"{__name__}:{function}"})


PLUGINS = [
    _plugin("Quit", "_exits"),
    _plugin("CtrlC", "_interrupts"),
    _plugin("Stall", "_stalls"),
    _plugin("Spin", "_spins"),
    _plugin("Step", "_steps"),
    _plugin("BadLog", "_bad_log"),
]
EXITING = pytest.mark.parametrize(
    ("name", "raised"), [("Quit", "SystemExit(3)"), ("CtrlC", "KeyboardInterrupt()")]
)
HANGING = pytest.mark.parametrize("name", ["Stall", "Spin"])


@pytest.fixture
def plugins() -> Iterator[PluginRegistry]:
    global _release
    _release = threading.Event()
    _calls.clear()
    yield PluginRegistry(PLUGINS)
    _release.set()


def command(registry: PluginRegistry, name: str) -> PluginAction:
    decoded = decode_command(name, (), registry.specs())
    assert isinstance(decoded, PluginAction)
    return decoded


# -- the registry's call: a thread of its own, a deadline ------------------------------------


def test_a_call_answers_with_the_value_or_the_failure_of_anything_raised(
    plugins: PluginRegistry,
) -> None:
    view = SimView("D1", 0.0, 0.0, 0.0, 2.0, 0.0, True, False)
    ok = plugins.call("Step", "sim", (view, command(plugins, "Step")), DEADLINE_S).wait()
    assert ok.failed == "" and ok.value == SimOutcome(duration_s=0.4, payload={"steps": 1.0})
    for name, raised in (("Quit", "SystemExit(3)"), ("CtrlC", "KeyboardInterrupt()")):
        answer = plugins.call(name, "sim", (view, command(plugins, name)), DEADLINE_S).wait()
        assert answer.failed == (
            f"plugin action {name!r} failed in its sim implementation: {raised}"
        )
    missing = plugins.call("Nope", "sim", (view, None), DEADLINE_S).wait()
    assert missing.failed == "no plugin provides action 'Nope'"


@HANGING
def test_a_call_that_hangs_fails_at_its_deadline_and_is_not_made_again(
    plugins: PluginRegistry, name: str
) -> None:
    view = SimView("D1", 0.0, 0.0, 0.0, 2.0, 0.0, True, False)
    args = (view, command(plugins, name))
    started = time.monotonic()
    call = plugins.call(name, "sim", args, DEADLINE_S)
    assert call.poll() is None  # running, its deadline ahead
    answer = call.wait()
    waited = time.monotonic() - started
    assert answer.failed == f"plugin action {name!r} did not finish within 1 s"
    assert DEADLINE_S <= waited < DEADLINE_S + PROMPT_S
    # Its thread may still run: a second call fails at once and starts no other.
    again = plugins.call(name, "sim", args, DEADLINE_S)
    assert again.poll() is not None
    assert "did not finish within 1 s before: not called again" in again.wait().failed
    assert _calls == [name]


# -- the simulator's core, stepped in virtual time -------------------------------------------


class Core:
    """A started core (virtual time: it waits for a plugin's outcome, at most the deadline)."""

    def __init__(self, plugins: PluginRegistry) -> None:
        settings = SimSettings(plugin_deadline_s=DEADLINE_S, arm_delay_s=0.0)
        self.core = SimCore("D1", settings, make_logger(None), plugins=plugins)
        self.core.start()
        self.plugins = plugins

    def do(self, name: str, cmd: Any = None, max_s: float = 120.0) -> ActionResult:
        done = Done()
        self.core.run(cmd if cmd is not None else command(self.plugins, name), done)
        for _ in range(round(max_s / SIM_DT_S)):
            for callback, result in self.core.step()[0]:
                callback(result)
            if done.is_done:
                return done.wait(0)
        raise AssertionError(f"{name} not finished in {max_s} simulated s")


@EXITING
def test_in_virtual_time_a_plugin_that_exits_fails_its_action_only(
    plugins: PluginRegistry, name: str, raised: str
) -> None:
    rig = Core(plugins)
    assert rig.do("Arm", decode_command("Arm", ())).ok
    assert rig.do("Takeoff", Takeoff(2.0)).ok
    result = rig.do(name)
    assert result.status == "failed" and raised in result.reason
    assert rig.do("Land", decode_command("Land", ())).ok
    assert rig.do("Disarm", decode_command("Disarm", ())).ok


@HANGING
def test_in_virtual_time_a_plugin_that_hangs_fails_at_its_deadline_in_the_same_step(
    plugins: PluginRegistry, name: str
) -> None:
    rig = Core(plugins)
    assert rig.do("Arm", decode_command("Arm", ())).ok
    t0 = rig.core.t_s
    result = rig.do(name)
    assert result.reason == f"plugin action {name!r} did not finish within 1 s"
    # Simulated time did not move while the step waited: the run stays the same run.
    assert rig.core.t_s == pytest.approx(t0 + SIM_DT_S)
    assert rig.do("Disarm", decode_command("Disarm", ())).ok


def test_a_plugin_outcome_the_simulator_cannot_use_fails_its_action(
    plugins: PluginRegistry,
) -> None:
    rig = Core(plugins)
    result = rig.do("BadLog")
    assert result.status == "failed"
    assert "SimOutcome.log uses field(s) the adapter log writes itself: action, handle" in (
        result.reason
    )
    started = rig.core.t_s
    assert rig.do("Step").ok  # the duration counts from the action's start
    assert rig.core.t_s - started == pytest.approx(0.4, abs=2 * SIM_DT_S)


# -- the simulated vehicle in real time ----------------------------------------------------


@pytest.fixture
def flying(tmp_path: Path, plugins: PluginRegistry) -> Iterator[Any]:
    """``flying(**hal)``: a simulated vehicle (speedup 10) hovering at 2 m, armed."""
    made: list[tuple[SimAdapter, Any]] = []

    def make(**hal: Any) -> SimAdapter:
        log = make_logger(tmp_path / "adapter.log", drone="D1")
        settings = SimSettings.from_mapping({"speedup": 10, **hal})
        adapter = SimAdapter("D1", settings, log, plugins)
        made.append((adapter, log))
        adapter.start(TelemetrySink())
        assert do(adapter, "Arm").ok
        assert do(adapter, "Takeoff", 2.0).ok
        return adapter

    yield make
    for adapter, log in made:
        started = time.monotonic()
        adapter.close()
        assert time.monotonic() - started < PROMPT_S  # the simulator thread ended
        close_logger(log)


def landed_and_disarmed(adapter: SimAdapter) -> bool:
    return adapter.wait_until(lambda s: s.landed and not s.armed, WAIT_S)


@EXITING
def test_a_plugin_that_exits_fails_its_action_and_the_vehicle_lands(
    flying: Any, plugins: PluginRegistry, name: str, raised: str
) -> None:
    sim = flying()
    done = Done()
    sim.run(command(plugins, name), done)
    result = done.wait(PROMPT_S)
    assert result.status == "failed" and result.reason.endswith(raised)
    assert do(sim, "Land").ok and do(sim, "Disarm").ok
    assert landed_and_disarmed(sim)


@HANGING
def test_a_plugin_that_hangs_fails_at_its_deadline_and_the_vehicle_lands(
    flying: Any, plugins: PluginRegistry, name: str
) -> None:
    sim = flying(plugin_deadline_s=DEADLINE_S)
    done = Done()
    started = time.monotonic()
    sim.run(command(plugins, name), done)
    result = done.wait(DEADLINE_S + PROMPT_S)
    assert time.monotonic() - started >= DEADLINE_S
    assert result.reason == f"plugin action {name!r} did not finish within 1 s"
    assert do(sim, "Land").ok and do(sim, "Disarm").ok
    assert landed_and_disarmed(sim)


@HANGING
def test_while_a_plugin_hangs_the_simulator_flies_on_and_an_abort_lands_the_vehicle(
    flying: Any, plugins: PluginRegistry, name: str
) -> None:
    sim = flying()  # the default deadline (10 s): the abort comes first
    done = Done()
    sim.run(command(plugins, name), done)
    # The simulator goes on ticking while the implementation runs (the predicate is
    # called after each tick): its clock moves, and the vehicle can be commanded.
    t0 = sim.sim_time_s
    ticks = itertools.count()
    assert sim.wait_until(lambda _: next(ticks) >= 10, WAIT_S)
    assert sim.sim_time_s > t0 and not done.is_done
    sim.abort()
    assert done.wait(PROMPT_S) == ActionResult("cancelled", "aborted")
    assert landed_and_disarmed(sim)


def test_a_plugin_action_in_real_time_logs_its_outcome_and_takes_its_duration(
    flying: Any, plugins: PluginRegistry, tmp_path: Path
) -> None:
    sim = flying()
    done = Done()
    sim.run(command(plugins, "Step"), done)
    assert done.wait(PROMPT_S).ok
    events = read_log(tmp_path / "adapter.log")
    [end] = [e for e in events if e["event"] == "adapter.action.end" and e["action"] == "Step"]
    assert end["duration_sim_s"] == pytest.approx(0.4, abs=0.05)
    assert end["payload"] == {"steps": 1.0}
