"""Property-based tests: random missions keep the slicing invariants; junk never crashes.

Random missions nest SEQ_/PAR_ blocks of actions on 1 to 4 drones with every
control structure (If, Wait*, Repeat*, Pause*, Do*), including an Exit
block shared by sibling structures of a PAR block.  Example counts are
bounded (``EAMOS_HYPOTHESIS_EXAMPLES`` scales them) and derandomised so CI
runs are reproducible.
"""

from __future__ import annotations

import itertools
import os
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from eamos.compiler import CompiledMission, MissionError, compile_mission
from eamos.program.format import load_program

from .compiler_helpers import mission_files

SCALE = float(os.environ.get("EAMOS_HYPOTHESIS_EXAMPLES", "1"))


def _settings(n: int) -> settings:
    return settings(
        max_examples=max(1, int(n * SCALE)),
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )


# -- a random mission, as a tree that renders to mission text ---------------------------

ACTIONS: list[tuple[str, int]] = [
    ("Arm", 0),
    ("Takeoff", 1),
    ("Land", 0),
    ("FlyByX", 1),
    ("FlyByY", 1),
    ("FlyByZ", 1),
    ("FlyToXYZ", 3),
    ("PauseFor", 1),
    ("TurnOn", 0),
    ("Calibrate", 0),
    ("TurnOnCamera", 0),
]
PROPS = ["X", "Y", "Z", "Battery"]
CONTROLS = [
    "If",
    "WaitWhile",
    "WaitUntil",
    "RepeatWhile",
    "RepeatUntil",
    "RepeatFor",
    "DoWhile",
    "DoUntil",
]

drone_index = st.integers(min_value=1, max_value=4)
comparison = st.tuples(
    drone_index,
    st.sampled_from(PROPS),
    st.sampled_from(["<", ">", ">="]),
    st.integers(min_value=-5, max_value=90),
)
condition = st.lists(comparison, min_size=1, max_size=3)

action = st.tuples(st.just("act"), drone_index, st.sampled_from(ACTIONS))
pause = st.one_of(
    st.tuples(st.just("pause_for"), st.integers(min_value=1, max_value=5)),
    st.tuples(
        st.just("pause"),
        st.sampled_from(["PauseWhile", "PauseUntil"]),
        st.one_of(st.none(), drone_index),
        condition,
    ),
)
leaf = st.one_of(action, action, action, pause)


def _block(children: Any) -> Any:
    return st.tuples(
        st.just("block"),
        st.sampled_from(["SEQ", "PAR"]),
        st.lists(children, min_size=1, max_size=4),
        st.booleans(),
    )


def _extend(children: Any) -> Any:
    block = _block(children)
    control = st.tuples(
        st.just("ctl"),
        st.sampled_from(CONTROLS),
        condition,
        st.integers(min_value=0, max_value=3),
        block,
        st.one_of(st.none(), block),
    )
    # A PAR block of loops/Dos naming one Exit block (experiment D's shape).
    with_exit = st.tuples(
        st.just("ctl"),
        st.sampled_from(CONTROLS[3:]),
        condition,
        st.integers(min_value=0, max_value=3),
        block,
        block,
    )
    shared = st.tuples(
        st.just("block"),
        st.just("PAR"),
        st.lists(st.one_of(with_exit, children), min_size=2, max_size=4),
        st.just(True),
    )
    return st.one_of(block, control, shared)


statement = st.recursive(leaf, _extend, max_leaves=14)
mission_tree = st.tuples(_block(statement), st.booleans())


@dataclass
class _Renderer:
    """Turns a random tree into mission text, one block per call site."""

    blocks: list[str] = field(default_factory=list)
    drones: set[int] = field(default_factory=set)
    counter: itertools.count = field(default_factory=itertools.count)  # type: ignore[type-arg]

    def cond(self, parts: list[tuple[int, str, str, int]]) -> str:
        self.drones.update(d for d, _, _, _ in parts)
        return " && ".join(f"Drone{d}.{p}() {op} {v}" for d, p, op, v in parts)

    def block(self, tree: tuple[Any, ...], name: str | None = None) -> str:
        _, mode, stmts, share = tree
        name = name or f"{mode}_B{next(self.counter)}"
        lines: list[str] = []
        shared_exit: str | None = None
        for stmt in stmts:
            exit_name = None
            if (
                share
                and mode == "PAR"
                and stmt[0] == "ctl"
                and stmt[5] is not None
                and stmt[1].startswith(("Repeat", "Do"))
            ):
                # Sibling structures naming the same Exit block share one instance of it.
                if shared_exit is None:
                    shared_exit = self.block(stmt[5])
                exit_name = shared_exit
            lines.append(self.statement(stmt, exit_name))
        body = "\n".join(f"\t{line}" for line in lines)
        self.blocks.append(f"func {name}() {{\n{body}\n}}\n")
        return name

    def statement(self, stmt: tuple[Any, ...], exit_name: str | None = None) -> str:
        kind = stmt[0]
        if kind == "act":
            _, d, (act, nargs) = stmt
            self.drones.add(d)
            args = {0: "", 1: "1.5", 3: "1, 2, 3"}[nargs]
            return f"Drone{d}.{act}({args})"
        if kind == "pause_for":
            return f"PauseFor({stmt[1]})"
        if kind == "pause":
            _, which, d, cond = stmt
            if d is not None:
                self.drones.add(d)
            prefix = f"Drone{d}." if d is not None else ""
            return f"{prefix}{which}({self.cond(cond)})"
        if kind == "block":
            return f"{self.block(stmt)}()"
        _, ctl, cond, count, body, second = stmt
        head = str(count) if ctl == "RepeatFor" else self.cond(cond)
        parts = [head, self.block(body)]
        if ctl.startswith("Wait"):
            pass  # WaitWhile/WaitUntil take no second block
        elif exit_name is not None:
            parts.append(exit_name)
        elif second is not None:
            parts.append(self.block(second))
        return f"{ctl}({', '.join(parts)})"


def render(tree: tuple[Any, ...]) -> str:
    """Mission text for a random tree (drones declared, entry block first)."""
    root, with_init = tree
    r = _Renderer()
    entry = r.block(root)
    if with_init:
        r.blocks.append(f"func INIT() {{\n\t{entry}()\n}}\n")
    decls = "".join(f"var Drone{d} Quadcopter\n" for d in sorted(r.drones))
    # Entry first, so it is the mission's first block when there is no INIT.
    ordered = [r.blocks[-1], *r.blocks[:-1]]
    return "package random\n\n" + decls + "\n" + "\n".join(ordered)


# -- invariants -------------------------------------------------------------------------------


def _without_loops(g: nx.DiGraph) -> nx.DiGraph:
    return nx.subgraph_view(g, filter_edge=lambda a, b: g.edges[a, b].get("kind") != "loop")


def check_invariants(c: CompiledMission) -> None:
    meg, mdgs = c.meg, c.mdgs
    fork = {n for n, a in meg.nodes(data=True) if a["kind"] == "fork"}
    host = {n: a["drone"] for n, a in meg.nodes(data=True)}

    # 1. Every non-fork MEG node is native in exactly one MDG: its drone's.
    for n in meg:
        if n in fork:
            continue
        natives = [d for d, g in mdgs.items() if f"n{n}" in g and g.nodes[f"n{n}"]["native"]]
        assert natives == [host[n]], (n, natives)
    for d, g in mdgs.items():
        for _key, a in g.nodes(data=True):
            assert a["native"] == (a["drone"] == d)
            assert a["meg"] in meg

    # 2. External arcs pair up exactly: one out arc in the sender's MDG, one in arc
    #    in the receiver's, under the same keys; internal arcs join natives only.
    outs: Counter[tuple[str, str]] = Counter()
    ins: Counter[tuple[str, str]] = Counter()
    for d, g in mdgs.items():
        for a, b, data in g.edges(data=True):
            na, nb = g.nodes[a]["native"], g.nodes[b]["native"]
            if data["external"]:
                assert na != nb, (d, a, b)
                if na:
                    outs[(a, b)] += 1
                    assert g.nodes[b]["drone"] in mdgs and (a, b) in mdgs[g.nodes[b]["drone"]].edges
                else:
                    ins[(a, b)] += 1
                    assert (a, b) in mdgs[g.nodes[a]["drone"]].edges
            else:
                assert na and nb, (d, a, b)
            assert data["kind"] == meg.edges[g.nodes[a]["meg"], g.nodes[b]["meg"]]["kind"]
    assert outs == ins
    assert max(outs.values(), default=1) == 1

    # 3. Every MEG arc between non-forks of different drones is one such external arc.
    for a, b in meg.edges:
        if a in fork or b in fork:
            continue
        key = (f"n{a}", f"n{b}")
        if host[a] != host[b]:
            assert outs[key] == 1 and mdgs[host[a]].edges[key]["external"]
            assert mdgs[host[b]].edges[key]["external"]
        else:
            assert not mdgs[host[a]].edges[key]["external"]

    # 4. Order: an MDG path between natives is a MEG path (every MDG arc is a MEG arc),
    #    and every MEG path between non-forks is a path in the MDGs glued by their keys
    #    (loop arcs ignored).  A drone's own MDG alone may lack the path: a -> fork ->
    #    (other drones) -> b reaches b only through the other drones' MDGs.
    meg_dag = _without_loops(meg)
    union = nx.DiGraph()
    for g in mdgs.values():
        union.add_edges_from(_without_loops(g).edges)
        union.add_nodes_from(g)
    for g in mdgs.values():
        local = _without_loops(g)
        natives = [k for k, a in g.nodes(data=True) if a["native"] and a["kind"] != "fork"]
        for k in natives:
            for k2 in nx.descendants(local, k):
                if g.nodes[k2]["native"]:
                    assert nx.has_path(meg_dag, g.nodes[k]["meg"], g.nodes[k2]["meg"])
    for n in meg:
        if n in fork:
            continue
        reach = nx.descendants(union, f"n{n}") if f"n{n}" in union else set()
        for m in nx.descendants(meg_dag, n):
            if m not in fork:
                assert f"n{m}" in reach, (n, m)

    # 5. Programs mirror their MDGs.
    for d, p in c.programs.items():
        assert {n.key for n in p.nodes} == set(mdgs[d].nodes)
        assert {(a.src, a.dst) for a in p.arcs} == set(mdgs[d].edges)


@_settings(200)
@given(mission_tree)
def test_random_missions_keep_the_slicing_invariants(tree: tuple[Any, ...]) -> None:
    source = render(tree)
    compiled = compile_mission(source, "random.go")
    check_invariants(compiled)


@_settings(25)
@given(mission_tree)
def test_random_mission_programs_round_trip(tree: tuple[Any, ...]) -> None:
    compiled = compile_mission(render(tree), "random.go")
    with tempfile.TemporaryDirectory() as tmp:
        for drone, program in compiled.programs.items():
            path = program.save(Path(tmp) / f"{drone}.program.json")
            loaded = load_program(path)
            assert loaded == program
            assert loaded.checksum == program.checksum


def _features(stmt: Any) -> set[str]:
    """Control structures and shared Exit blocks a random tree contains."""
    out: set[str] = set()
    kind = stmt[0]
    if kind == "pause":
        out.add(stmt[1] + ("@drone" if stmt[2] is not None else ""))
    elif kind == "pause_for":
        out.add("PauseFor")
    elif kind == "block":
        _, mode, stmts, share = stmt
        out.add(mode)
        exits = [
            s
            for s in stmts
            if s[0] == "ctl" and s[5] is not None and s[1].startswith(("Repeat", "Do"))
        ]
        if share and mode == "PAR" and len(exits) >= 2:
            out.add("shared exit")
        for sub in stmts:
            out |= _features(sub)
    elif kind == "ctl":
        out.add(stmt[1])
        out |= _features(stmt[4])
        if stmt[5] is not None:
            out |= _features(stmt[5])
    return out


def test_the_generator_reaches_every_structure() -> None:
    """Guard against a generator that silently stopped producing some construct."""
    seen: set[str] = set()
    sizes: list[int] = []

    @_settings(300)
    @given(mission_tree)
    def collect(tree: tuple[Any, ...]) -> None:
        seen.update(_features(tree[0]))
        sizes.append(render(tree).count("\n"))

    collect()
    wanted = {
        *CONTROLS,
        "PauseWhile",
        "PauseUntil",
        "PauseWhile@drone",
        "PAR",
        "SEQ",
        "PauseFor",
        "shared exit",
    }
    assert wanted <= seen, wanted - seen
    assert max(sizes) >= 40  # some missions are big enough to be interesting


def test_paper_missions_keep_the_slicing_invariants() -> None:
    for path in mission_files():
        check_invariants(compile_mission(path.read_text(encoding="utf-8"), path.name))


# -- fuzzing: junk and damaged listings raise MissionError only ----------------------------------

_LISTINGS = [p.read_text(encoding="utf-8") for p in mission_files()]


def _compile_or_mission_error(text: str) -> None:
    try:
        compiled = compile_mission(text, "fuzz.go")
    except MissionError as exc:
        rendered = exc.render("fuzz.go", text)
        assert rendered.startswith("fuzz.go:")
        return
    check_invariants(compiled)


@_settings(300)
@given(st.text(max_size=300))
def test_random_text_never_crashes(text: str) -> None:
    _compile_or_mission_error(text)


@_settings(300)
@given(
    st.text(
        alphabet=st.sampled_from(
            list('func SEQ_PAR_(){}\n\t.,;:=<>&|!-+*/"0123456789DroneXYZ Takeoff RepeatWhile If')
        ),
        max_size=200,
    )
)
def test_go_like_junk_never_crashes(text: str) -> None:
    _compile_or_mission_error(text)


mutation = st.tuples(
    st.sampled_from(["delete", "insert", "replace", "swap_lines", "duplicate"]),
    st.floats(min_value=0, max_value=1),
    st.integers(min_value=1, max_value=12),
    st.text(alphabet=st.sampled_from(list("(){},.;\n\t\"'0123456789-_xXyY&|!=<>")), max_size=6),
)


@_settings(400)
@given(st.sampled_from(range(len(_LISTINGS))), st.lists(mutation, min_size=1, max_size=4))
def test_mutated_listings_never_crash(index: int, mutations: list[tuple[Any, ...]]) -> None:
    text = _LISTINGS[index]
    for op, where, size, junk in mutations:
        pos = int(where * len(text))
        if op == "delete":
            text = text[:pos] + text[pos + size :]
        elif op == "insert":
            text = text[:pos] + junk + text[pos:]
        elif op == "replace":
            text = text[:pos] + junk + text[pos + size :]
        elif op == "duplicate":
            text = text[:pos] + text[pos : pos + size * 4] + text[pos:]
        else:
            lines = text.split("\n")
            i = int(where * (len(lines) - 1))
            j = min(len(lines) - 1, i + size)
            lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
    _compile_or_mission_error(text)
