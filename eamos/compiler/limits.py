"""The compiler's caps, and the checks that keep every phase bounded.

Each cap is far above what a person writes (the paper's largest mission has
20 drones and about 5 000 nodes) and low enough that no input can exhaust the
Python stack, the memory or the patience of the operator: a mission at a cap
compiles, one past it is a located :class:`~.errors.MissionError`.  The caps
are stated in ``docs/mission-language.md`` ("Limits"); keep both in step.

The block checks here walk the block-call graph iteratively and count *before*
anything is expanded, so a short file whose blocks call each other many times
(2^20 nodes from 739 bytes) is refused in microseconds.
"""

from __future__ import annotations

from collections.abc import Iterator

from ..program.conditions import MAX_DEPTH as _CONDITION_DEPTH
from .errors import Diagnostic, SourceLocation
from .syntax import (
    ActionCall,
    Block,
    BlockCall,
    BlockRef,
    Control,
    Mission,
    flat_statements,
    named_drone_calls,
)

#: Largest mission file, in UTF-8 bytes.
MAX_SOURCE_BYTES = 2_000_000
#: Most errors reported for one file (the rest are counted); and a file longer than
#: PROBE_BYTES whose first PROBE_BYTES hold more syntax errors than this is refused
#: after parsing only those: junk is not mission text, whatever follows.
MAX_ERRORS = 100
PROBE_BYTES = 65_536
#: Only files longer than this are probed: a shorter one is parsed whole at little cost,
#: and a probe's cut can make a valid file look like junk (4 000 nested loops cut open).
PROBE_FROM_BYTES = 262_144
#: Longest name (drone, block, drone type, package): names become file names.
MAX_NAME_CHARS = 64
#: ... and at most this many UTF-8 bytes (64 four-byte letters would not fit a file name).
MAX_NAME_BYTES = 128
#: Deepest nesting of operators and parentheses in one condition or argument.
MAX_EXPRESSION_DEPTH = _CONDITION_DEPTH
#: Deepest nesting of blocks (block calls and control-structure blocks) from the entry.
MAX_BLOCK_DEPTH = 100
#: Most mission-tree nodes once every block call is expanded (each call copies the block).
MAX_TREE_NODES = 50_000
#: Most fork synchronisation arcs: for each PAR block, the branches ending right before
#: it times the drones it starts (each must hear of each); quadratic, so capped apart.
MAX_SYNC_ARCS = 100_000
#: Most drones in one mission (every program lists the whole fleet).
MAX_DRONES = 1_000
#: Most repetitions of RepeatFor.
MAX_REPEAT = 1_000_000
#: Largest distance, coordinate or height in metres (FlyBy*, FlyToXYZ, Takeoff, alt_m).
MAX_DISTANCE_M = 10_000.0
#: Longest pause in seconds (one day).
MAX_DURATION_S = 86_400.0
#: Fastest speed SetSpeed may ask for, in metres per second.
MAX_SPEED_M_S = 30.0
#: Largest Orbit radius in metres, and most turns of one Orbit.
MAX_ORBIT_RADIUS_M = 1_000.0
MAX_ORBIT_TURNS = 100.0
#: Most drone types one mission declares (with its libraries).
MAX_DRONE_TYPES = 200
#: Most libraries one mission imports, directly or through other libraries.
MAX_LIBRARIES = 64
#: Most .go files in one library folder.
MAX_LIBRARY_FILES = 100
#: Most parameters of one block.
MAX_PARAMS = 32
#: Most ``for`` loops nested in each other inside one block.
MAX_LOOP_DEPTH = 10
#: Largest whole number the compiler computes with (loop counters, indices): 2^53, so that
#: every one is also exact as a float64 on the drones.
MAX_WHOLE = 2**53

# Sizes above this are only "very large": no need to carry 2^100000 around.
_SATURATE = 10**15


def _refs(stmt: object) -> Iterator[BlockRef | BlockCall]:
    if isinstance(stmt, BlockCall):
        yield stmt
    elif isinstance(stmt, Control):
        for ref in (stmt.body, stmt.orelse, stmt.exit):
            if ref is not None:
                yield ref


def _own_nodes(block: Block) -> int:
    """Mission-tree nodes of a block besides its callees: itself, actions, controls.

    A Whenever counts twice: it and the ``seq`` node holding the statements it guards.
    """
    return 1 + sum(
        2 if isinstance(s, Control) and s.kind == "Whenever" else 1
        for s in flat_statements(block.statements)
        if isinstance(s, ActionCall | Control)
    )


class _BlockSizes:
    """Expanded size and nesting depth of every block reachable from the entry.

    Computed bottom-up by an explicit-stack depth-first walk (no recursion), on a
    mission whose blocks do not call each other in a cycle (checked before).
    """

    def __init__(self, mission: Mission) -> None:
        self.blocks = mission.blocks
        self.size: dict[str, int] = {}
        self.depth: dict[str, int] = {}
        # The call leading to each block's deepest callee, to show where nesting overflows.
        self.deepest: dict[str, BlockRef | BlockCall | None] = {}
        if mission.entry in self.blocks:
            self._walk(mission.entry)

    def _callees(self, name: str) -> list[BlockRef | BlockCall]:
        statements = flat_statements(self.blocks[name].statements)
        return [r for s in statements for r in _refs(s) if r.name in self.blocks]

    def _walk(self, entry: str) -> None:
        on_path: set[str] = {entry}
        stack: list[tuple[str, Iterator[BlockRef | BlockCall]]] = [
            (entry, iter(self._callees(entry)))
        ]
        while stack:
            name, pending = stack[-1]
            for ref in pending:
                if ref.name not in self.size and ref.name not in on_path:
                    on_path.add(ref.name)
                    stack.append((ref.name, iter(self._callees(ref.name))))
                    break
            else:
                stack.pop()
                on_path.discard(name)
                self._finish(name)

    def _finish(self, name: str) -> None:
        size = _own_nodes(self.blocks[name])
        depth, deepest = 0, None
        for ref in self._callees(name):
            size += self.size.get(ref.name, 0)  # absent only on a cycle, reported elsewhere
            if self.depth.get(ref.name, 0) > depth:
                depth, deepest = self.depth[ref.name], ref
        self.size[name] = min(size, _SATURATE)
        self.depth[name] = depth + 1
        self.deepest[name] = deepest


def amount(n: int) -> str:
    """A count as the messages print it: ``98 303``; saturated sizes as 'at least ...'."""
    return (
        f"at least {_SATURATE:,}".replace(",", " ")
        if n >= _SATURATE
        else f"{n:,}".replace(",", " ")
    )


def block_limit_errors(mission: Mission) -> list[Diagnostic]:
    """Errors for a mission nesting blocks too deep or expanding to too many nodes.

    Call only on a mission without recursion between blocks.
    """
    if mission.entry not in mission.blocks:
        return []
    sizes = _BlockSizes(mission)
    out: list[Diagnostic] = []
    entry = mission.entry
    if sizes.depth[entry] > MAX_BLOCK_DEPTH:
        path, ref = [entry], sizes.deepest[entry]
        last_ref = ref
        while ref is not None and len(path) <= MAX_BLOCK_DEPTH:
            path.append(ref.name)
            last_ref = ref
            ref = sizes.deepest[ref.name]
        assert last_ref is not None  # deeper than the limit: the path has callees
        shown = " -> ".join([*path[:3], "...", *path[-2:]])
        out.append(
            Diagnostic(
                "error",
                last_ref.loc,
                f"blocks nest {sizes.depth[entry]} deep from {entry}, more than the limit of "
                f"{MAX_BLOCK_DEPTH}: here {path[-2]} enters {path[-1]} ({shown})",
                "call the blocks one after another in a SEQ_ block instead of each from the last",
                last_ref.loc.col + len(last_ref.name),
            )
        )
    if sizes.size[entry] > MAX_TREE_NODES:
        culprit = entry
        while True:
            bigger = [r for r in sizes._callees(culprit) if sizes.size[r.name] > MAX_TREE_NODES]
            if not bigger:
                break
            culprit = max(bigger, key=lambda r: sizes.size[r.name]).name
        out.append(_too_big(mission, sizes, entry, culprit))
    return out


def _too_big(mission: Mission, sizes: _BlockSizes, entry: str, culprit: str) -> Diagnostic:
    calls: dict[str, int] = {}
    for ref in sizes._callees(culprit):
        calls[ref.name] = calls.get(ref.name, 0) + 1
    hint = "use RepeatFor(n, Body) to repeat a block instead of calling it many times"
    if calls:
        top = max(calls, key=lambda n: calls[n] * sizes.size[n])
        times = "once" if calls[top] == 1 else "twice" if calls[top] == 2 else f"{calls[top]} times"
        hint = (
            f"it calls {top} {times} and every call copies {top} "
            f"({amount(sizes.size[top])} nodes); " + hint
        )
    whole = "" if culprit == entry else f" (the whole mission: {amount(sizes.size[entry])})"
    block = mission.blocks[culprit]
    return Diagnostic(
        "error",
        block.loc,
        f"block '{culprit}' expands to {amount(sizes.size[culprit])} mission-tree nodes, "
        f"more than the limit of {amount(MAX_TREE_NODES)}{whole}",
        hint,
        block.loc.col + len(culprit),
    )


def fleet_limit_error(mission: Mission) -> Diagnostic | None:
    """An error at the first drone past :data:`MAX_DRONES`, in order of appearance.

    A group counts its members (declared groups first: their members are drones).
    """
    members = 0
    for group in mission.groups.values():
        members += group.size
        if members > MAX_DRONES:
            return Diagnostic(
                "error",
                group.loc,
                f"the mission commands more than {MAX_DRONES:,} drones; group "
                f"'{group.name}' ({group.size}) crosses the limit".replace(",", " "),
                "split the fleet into several missions",
                group.loc.col + len(group.name),
            )
    seen: dict[str, SourceLocation] = {d.name: d.loc for d in mission.drones.values()}
    if len(seen) + members <= MAX_DRONES:
        for call in named_drone_calls(mission):
            seen.setdefault(call.drone or "", call.loc)
    if len(seen) + members <= MAX_DRONES:
        return None
    name, loc = list(seen.items())[MAX_DRONES - members]
    return Diagnostic(
        "error",
        loc,
        f"the mission commands more than {MAX_DRONES:,} drones; '{name}' is one too many".replace(
            ",", " "
        ),
        "split the fleet into several missions",
        loc.col + len(name),
    )


def name_error(name: str, loc: SourceLocation) -> Diagnostic | None:
    """An error if ``name`` is too long to be a drone, block, type or package name."""
    if len(name) <= MAX_NAME_CHARS and len(name) * 4 <= MAX_NAME_BYTES:
        return None
    size = len(name.encode("utf-8", errors="surrogatepass"))
    if len(name) <= MAX_NAME_CHARS and size <= MAX_NAME_BYTES:
        return None
    shown = name[:20] + "..."
    what = (
        f"{len(name)} characters long, more than the limit of {MAX_NAME_CHARS}"
        if len(name) > MAX_NAME_CHARS
        else f"{size} bytes in UTF-8, more than the limit of {MAX_NAME_BYTES}"
    )
    return Diagnostic(
        "error",
        loc,
        f"the name '{shown}' is {what}",
        "names become file names on the drones: use a shorter name",
        loc.col + len(name),
    )
