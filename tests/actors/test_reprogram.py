"""An amendment on a drone (issue 31): which node actors change, and how a node is held.

Pure: :func:`program_change` and :func:`change_refusal` on the four-lane mission and
its amendments, renumbered as ``eamos amend`` does; :func:`apply_refusal` for the whole
fleet; :func:`reroute_emits`.  Then node actors on a real dispatcher, their peers
recorders: a node not yet begun is held, keeps what it is given and hands it to its
replacement; a node that has begun is not held; a redirected node holds the triggers
it sends and sends them to its new successors, or to its old ones when the amendment
is cancelled.  The same through real processes: ``tests/operator/test_amend_apply.py``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from eamos.actors.amendable import Amendable, AmendNode, reroute_emits
from eamos.actors.dispatch import Dispatcher
from eamos.actors.logic import Emit, PassThrough, Route
from eamos.actors.messages import NodeResolved, Trigger
from eamos.actors.node import Links, MissionNode, Wire
from eamos.actors.reprogram import change_refusal, program_change
from eamos.compiler import compile_mission
from eamos.compiler.amendment import rekey
from eamos.ground.amend import apply_refusal, changed_drones
from eamos.logs import close_logger, make_logger
from eamos.program.format import ProgramNode
from tests.support.four_lanes import LANES, LATER_PARTS, TEXT, amended

from .recorder import WAIT_S, Recorder


def programs(text: str) -> dict[str, Any]:
    """The programs of ``text``, renumbered against the four lanes as written."""
    running = compile_mission(TEXT, str(LANES)).programs
    return dict(rekey(running, compile_mission(text, str(LANES))).programs)


RUNNING = programs(TEXT)


def labels(program: Any, keys: tuple[str, ...]) -> list[str]:
    return [program.node(k).label for k in keys]


def test_an_amendment_changes_the_actors_of_the_nodes_it_changes_only() -> None:
    new = programs(amended(*LATER_PARTS))
    assert changed_drones(RUNNING, new) == ["Drone3", "Drone4"]
    three = program_change(RUNNING["Drone3"], new["Drone3"])
    # The way back becomes two legs: the first is the old leg changed, the second new;
    # Land waits for the new one (its incoming arc changes); the first leg is redirected.
    assert labels(new["Drone3"], three.added) == ["FlyByX(-6)"]
    assert labels(new["Drone3"], three.start) == ["FlyByX(-6)", "FlyByX(-6)", "Land()"]
    assert labels(RUNNING["Drone3"], three.retire) == ["FlyByX(-12)", "Land()"]
    assert three.removed == ()
    assert labels(RUNNING["Drone3"], three.reroute) == []  # FlyByX(12) is followed as before
    four = program_change(RUNNING["Drone4"], new["Drone4"])
    assert labels(new["Drone4"], four.added) == ["FlyByZ(1)"]
    assert labels(RUNNING["Drone4"], four.reroute) == ["FlyByX(12)"]  # now FlyByZ(1) follows
    assert labels(RUNNING["Drone4"], four.retire) == ["FlyByX(-12)"]
    # A drone the amendment does not touch: nothing changes, though its lines moved.
    one = program_change(RUNNING["Drone1"], new["Drone1"])
    assert (one.start, one.retire, one.reroute) == ((), (), ())
    assert change_refusal(RUNNING["Drone3"], new["Drone3"]) == ""
    assert apply_refusal(RUNNING, new) == ""


def test_what_needs_a_link_the_roll_out_did_not_make_is_refused() -> None:
    # Drone1 climbs after Drone4 landed: Drone4 would trigger Drone1, never linked to it.
    new = programs(amended(("\tDrone4.Land()\n", "\tDrone4.Land()\n\tDrone1.FlyByZ(1)\n")))
    why = change_refusal(RUNNING["Drone4"], new["Drone4"])
    assert why == "it would send to Drone1, which the roll-out did not link it to"
    assert apply_refusal(RUNNING, new).startswith("Drone4: it would send to Drone1")


def test_an_amendment_of_the_ground_stations_part_is_refused() -> None:
    # A bare pause beside the lanes: the ground station hosts it.
    new = programs(amended(("func PAR_Lanes() {\n", "func PAR_Lanes() {\n\tPauseFor(1)\n")))
    assert changed_drones(RUNNING, new) == ["GCS"]
    assert "ground station's own part" in apply_refusal(RUNNING, new)


def test_held_triggers_go_to_the_new_successors_with_the_status_of_their_kind() -> None:
    old = [
        Emit(Route("n5", "D1", "then", False), (), "done"),
        Emit(Route("n6", "D1", "else", False), (), "skipped"),
    ]
    new = (Route("n9", "D2", "then", True), Route("n6", "D1", "else", False))
    assert reroute_emits(old, new) == [
        Emit(new[0], (), "done"),
        Emit(new[1], (), "skipped"),
    ]
    # A node sends one status on every route: a new kind gets it too.
    plain = [Emit(Route("n5", "D1", "seq", False), (2,), "failed")]
    assert reroute_emits(plain, (Route("n7", "D1", "sync", False),)) == [
        Emit(Route("n7", "D1", "sync", False), (2,), "failed")
    ]


def test_a_node_that_waits_is_held_and_one_that_acted_is_not() -> None:
    join = Amendable()
    join.seen(Trigger("n1", "n3", (), "done"), [])  # one of its two preconditions
    assert join.hold_in()
    assert join.keeps(Trigger("n2", "n3", (), "done"))
    assert join.retire() == (Trigger("n1", "n3", (), "done"), Trigger("n2", "n3", (), "done"))
    ran = Amendable()
    ran.seen(Trigger("n1", "n3", (), "done"), [Emit(Route("n4", "D1", "seq", False), (), "done")])
    assert not ran.hold_in() and not ran.hold_out() and ran.kept == []


# -- node actors ------------------------------------------------------------------------------

JOIN = ProgramNode(key="n3", meg=3, kind="join", drone="D1", native=True, label="join")
OUT = (Route("n8", "D1", "seq", False),)
NEW_OUT = (Route("n9", "D1", "seq", False),)


@pytest.fixture
def node(tmp_path: Path) -> Iterator[tuple[Any, dict[str, Recorder]]]:
    """A join node ``n3`` (waiting for ``n1`` and ``n2``, followed by ``n8``); its peers."""
    dispatcher = Dispatcher(workers=1, name="test-amend")
    log = make_logger(tmp_path / "mission.log")
    peers = {name: Recorder(unpack_news=True) for name in ("n8", "n9", "hal", "board", "out", "ex")}
    links = Links(
        {"n8": peers["n8"], "n9": peers["n9"]},
        peers["hal"],
        peers["board"],
        peers["out"],
        peers["ex"],
    )
    entry = frozenset({"n1", "n2"})
    logic = PassThrough(JOIN, OUT, entry)
    ref = MissionNode.start(dispatcher, JOIN, OUT, entry, frozenset(), "D1", log, logic=logic)
    ref.tell(Wire(links))
    yield ref, peers
    ref.stop()
    dispatcher.shutdown()
    close_logger(log)


def triggers(recorder: Recorder) -> list[Trigger]:
    return [m for m in recorder.messages if isinstance(m, Trigger)]


def test_a_held_node_keeps_what_it_is_given_for_its_replacement(node: Any) -> None:
    ref, peers = node
    ref.tell(Trigger("n1", "n3", (), "done"))
    assert ref.ask(AmendNode("hold"), timeout=WAIT_S) is True
    ref.tell(Trigger("n2", "n3", (), "done"))  # would fire it: held, it keeps it
    kept = ref.ask(AmendNode("retire"), timeout=WAIT_S)
    assert kept == (Trigger("n1", "n3", (), "done"), Trigger("n2", "n3", (), "done"))
    assert triggers(peers["n8"]) == []


def test_a_held_node_released_acts_on_what_it_kept(node: Any) -> None:
    ref, peers = node
    ref.tell(Trigger("n1", "n3", (), "done"))
    assert ref.ask(AmendNode("hold"), timeout=WAIT_S) is True
    ref.tell(Trigger("n2", "n3", (), "done"))
    ref.tell(AmendNode("release"))
    assert peers["n8"].wait_for(Trigger) == Trigger("n3", "n8", (), "done")
    assert ref.ask(AmendNode("hold"), timeout=WAIT_S) is False  # it has begun now


def test_a_redirected_node_sends_what_it_held_to_its_new_successors(node: Any) -> None:
    ref, peers = node
    assert ref.ask(AmendNode("hold-out"), timeout=WAIT_S) is True
    ref.tell(Trigger("n1", "n3", (), "done"))
    ref.tell(Trigger("n2", "n3", (), "skipped"))
    peers["ex"].wait_for(NodeResolved)  # it ran: its trigger to n8 is held
    assert triggers(peers["n8"]) == []
    ref.tell(AmendNode("reroute", NEW_OUT))
    assert peers["n9"].wait_for(Trigger) == Trigger("n3", "n9", (), "done")
    assert triggers(peers["n8"]) == []
    assert ref.ask(AmendNode("hold-out"), timeout=WAIT_S) is False  # it has ended
