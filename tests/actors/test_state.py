"""The pure precondition bookkeeping, without threads (paper VI-B, Figure 9)."""

from eamos.actors.state import Preconditions, combine, holds, within


def test_node_fires_when_all_preconditions_arrived():
    pre = Preconditions(entry=frozenset({"a", "b", "c"}))
    assert pre.receive("a", (), "done") is None
    assert pre.receive("b", (), "done") is None
    assert set(pre.waiting()[("entry", ())]) == {"c"}
    fired = pre.receive("c", (), "done")
    assert fired is not None and fired.group == "entry" and fired.status == "done"


def test_duplicate_triggers_are_ignored_before_and_after_firing():
    pre = Preconditions(entry=frozenset({"a", "b"}))
    assert pre.receive("a", (), "done") is None
    assert pre.receive("a", (), "done") is None
    assert pre.receive("b", (), "done") is not None
    assert pre.receive("b", (), "done") is None
    assert pre.receive("a", (), "done") is None
    assert pre.duplicates == 3


def test_loop_iterations_never_mix():
    # A node inside one loop: its activation is the loop counter.
    pre = Preconditions(entry=frozenset({"x", "y"}), depth=1)
    assert pre.receive("x", (0,), "done") is None
    assert pre.receive("x", (1,), "done") is None
    fired = pre.receive("y", (1,), "done")
    assert fired is not None and fired.activation == (1,)
    fired = pre.receive("y", (0,), "done")
    assert fired is not None and fired.activation == (0,)


def test_loop_begin_has_entry_and_back_arc_groups():
    pre = Preconditions(entry=frozenset({"before"}), loop=frozenset({"last"}), depth=0)
    entry = pre.receive("before", (), "done")
    assert entry is not None and entry.group == "entry"
    first = pre.receive("last", (0,), "done")
    assert first is not None and first.group == "loop" and first.activation == (0,)
    assert pre.receive("last", (0,), "done") is None  # a duplicate of iteration 0
    second = pre.receive("last", (1,), "done")
    assert second is not None and second.activation == (1,)


def test_unknown_sources_are_not_counted():
    pre = Preconditions(entry=frozenset({"a"}))
    assert pre.receive("stranger", (), "done") is None
    assert pre.waiting() == {}


def test_initial_node_fires_once_without_arcs():
    pre = Preconditions(entry=frozenset())
    assert pre.fire_without_arcs() is not None
    assert pre.fire_without_arcs() is None


def test_combine_runs_if_any_ran_blocks_on_failure_skips_if_all_skipped():
    assert combine(["done", "skipped"]) == "done"  # the end of an If joins both branches
    assert combine(["skipped", "skipped"]) == "skipped"
    assert combine(["done", "failed"]) == "failed"
    assert combine([]) == "done"


def test_within_and_holds():
    assert within((2, 1), (2,)) and not within((3, 1), (2,)) and within((), ())
    assert holds("repeat_while", True) and not holds("repeat_until", True)
    assert holds("do_until", False)
