"""A damaged or hostile program file is a ProgramError (exit 2), never an internal error.

The checksum guards against damage, not against an edit: a program edited with its
checksum recomputed must still be refused field by field if it is not a program (and the
ground station refuses a drone running another program than the compiled one:
``tests/ground/test_program_checksum.py``).
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from eamos.compiler import compile_file
from eamos.program import DroneProgram, ProgramError, load_program, program_from_dict

REPO = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.timeout(600)


def sealed(doc: dict[str, Any]) -> dict[str, Any]:
    """``doc`` with its checksum recomputed, as an editor of the file would (the format's
    checksum: SHA-256 of the canonical JSON of everything but the checksum)."""
    body = {k: v for k, v in doc.items() if k != "checksum"}
    text = json.dumps(body, sort_keys=True, separators=(",", ":")).encode("utf-8")
    return {**body, "checksum": "sha256:" + hashlib.sha256(text).hexdigest()}


def test_a_program_of_100000_nested_arrays_is_refused_by_eamos_node(tmp_path: Path) -> None:
    program = tmp_path / "Drone1.program.json"
    program.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ProgramError, match="nested more than"):
        load_program(program)
    config = tmp_path / "node.toml"
    config.write_text(
        'drone = "Drone1"\nprogram = "Drone1.program.json"\n'
        '[net]\nbind = "tcp://127.0.0.1:6001"\nplain = true\n'
        '[net.peers]\nGCS = "tcp://127.0.0.1:6000"\n[hal]\nadapter = "sim"\n'
    )
    done = subprocess.run(
        [sys.executable, "-m", "eamos.cli.node", "--config", str(config)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert done.returncode == 2, done.stderr
    assert f"{program}: nested more than" in done.stderr and "internal" not in done.stderr


_LEAF = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=10),
)
_VALUE = st.recursive(
    _LEAF,
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3)
    ),
    max_leaves=10,
)


@pytest.fixture(scope="module")
def program_doc() -> dict[str, Any]:
    compiled = compile_file(REPO / "missions" / "experiment_c.go")
    return json.loads(compiled.programs["Drone1"].to_json())


def test_edited_programs_load_or_are_refused_never_crash(program_doc: dict[str, Any]) -> None:
    fields = [k for k in program_doc if k != "checksum"]
    node_keys = sorted({k for n in program_doc["nodes"] for k in n} | {"args", "loops", "count"})

    @settings(
        max_examples=600, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow]
    )
    @given(st.data())
    def one(data: st.DataObject) -> None:
        doc = copy.deepcopy(program_doc)
        for _ in range(data.draw(st.integers(1, 3))):
            where = data.draw(st.sampled_from(["top", "node", "arc"]))
            value = data.draw(_VALUE)
            if where == "top":
                doc[data.draw(st.sampled_from(fields))] = value
            elif where == "node" and isinstance(doc.get("nodes"), list) and doc["nodes"]:
                node = data.draw(st.sampled_from(doc["nodes"]))
                if isinstance(node, dict):
                    node[data.draw(st.sampled_from(node_keys))] = value
            elif isinstance(doc.get("arcs"), list) and doc["arcs"]:
                arc = data.draw(st.sampled_from(doc["arcs"]))
                if isinstance(arc, dict):
                    arc[data.draw(st.sampled_from(["src", "dst", "kind", "external"]))] = value
        try:
            program = program_from_dict(sealed(doc), "Drone1.program.json")
        except ProgramError as exc:
            assert str(exc).startswith("Drone1.program.json: ")
            return
        assert isinstance(program, DroneProgram)
        well_typed(program)

    one()


def well_typed(program: DroneProgram) -> None:
    """Every field of a loaded program has its type: what loads, the runtime can use."""
    assert all(isinstance(d, str) for d in (*program.fleet, *program.telemetry_from))
    for n in program.nodes:
        assert all(isinstance(a, float) and math.isfinite(a) for a in n.args), n
        for value in (n.count, n.begin, n.end, n.catch):
            assert value is None or (isinstance(value, int) and not isinstance(value, bool)), n
        ints = (*n.loops, *n.scopes, n.meg, n.catch_loops, n.catch_line, n.line, n.col)
        assert all(isinstance(i, int) and not isinstance(i, bool) for i in ints), n
        texts = (n.key, n.kind, n.drone, n.label, n.block, *n.interrupt_drones, *n.catch_drones)
        assert all(isinstance(t, str) for t in (*texts, *n.suspend_drones)), n
        assert n.action is None or isinstance(n.action, str), n
        assert n.interrupt_mode is None or isinstance(n.interrupt_mode, str), n
        assert all(isinstance(b, bool) for b in (n.native, n.suspendable, n.in_handler)), n
