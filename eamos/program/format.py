"""Drone mission programs: what the compiler ships to each drone.

A program is one JSON document per drone (``<Drone>.program.json``): its
Mission Dependency Graph as node and arc lists plus what the runtime needs to
run it.  It is versioned (``format``/``version``) and checksummed (SHA-256 of
the canonical JSON of everything but the checksum), and loads with the
standard library only: drones need neither the compiler nor tree-sitter.

Document fields (all required):

``format`` = ``"eamos-program"``, ``version`` = 1, ``checksum`` = ``"sha256:<hex>"``
``mission``       mission name (the Go package, or the file name)
``mission_id``    identity of the compiled mission (same in every program of it)
``drone``         the drone (or ``"GCS"``) this program runs on
``drone_type``    its drone type
``fleet``         every participant of the mission, ground station first
``telemetry_from`` drones whose properties this drone's conditions read
``nodes``         list of node objects (below)
``arcs``          list of ``{"src", "dst", "kind", "external"}`` (keys of nodes)
``source_file``   the mission file it was compiled from
``compiler``      the eamos version that compiled it

Optional field (absent when empty, so programs without it load and check as before):

``libraries``     the library files the mission was built from, as a list of
                  ``{"path", "sha256"}`` (the SHA-256 of each file's bytes)

Node object: ``key`` (``n<id>`` or ``n<id>@<drone>`` for fork replicas),
``meg`` (MEG id), ``kind``, ``drone`` (executing drone), ``native`` (runs
here; otherwise a proxy of a node on another drone), ``label``, and where
they apply ``action``, ``args``, ``cond``, ``count``, ``loops``, ``scopes``,
``begin``, ``end``, ``interrupt_drones``, ``interrupt_mode``, ``catch``,
``catch_loops``, ``catch_drones``, ``catch_line`` (nodes inside a Try's
Body: the Try that catches their failure), ``suspend_drones`` (on a
Whenever), ``suspendable`` and ``in_handler`` (actions a Whenever suspends,
actions of a Handler), ``line``, ``col``, ``block``.  The fields added for
Try and Whenever are absent where they do not apply, so programs without
them are unchanged.  See :mod:`eamos.compiler.execution_graph` for meanings.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import MISSING, dataclass, field, fields
from functools import cached_property
from pathlib import Path
from typing import Any

from .conditions import MAX_DEPTH as MAX_CONDITION_DEPTH
from .conditions import ConditionError, validate

FORMAT = "eamos-program"
VERSION = 1

NODE_KINDS = frozenset(
    {
        "init",
        "action",
        "fork",
        "end",
        "if",
        "wait_while",
        "wait_until",
        "pause_while",
        "pause_until",
        "repeat_while",
        "repeat_until",
        "repeat_for",
        "do_while",
        "do_until",
        "try",
        "whenever",
        "abandon",
    }
)
ARC_KINDS = frozenset({"seq", "then", "else", "body", "exit", "loop", "begin", "handler"})


class ProgramError(Exception):
    """A drone program file is missing, damaged, or of an unsupported version."""


#: Node fields that locate or describe rather than decide (see :meth:`ProgramNode.executed`).
_POSITION_FIELDS = ("line", "col", "catch_line")
_PROXY_DESCRIPTIVE = ("label", "action", "args", "cond", "count", "block")


@dataclass(frozen=True)
class ProgramNode:
    """One MDG node (native, or a proxy for a node of another drone)."""

    key: str
    meg: int
    kind: str
    drone: str
    native: bool
    label: str = ""
    action: str | None = None
    args: tuple[float, ...] = ()
    cond: list[Any] | None = field(default=None, hash=False)
    count: int | None = None
    loops: tuple[int, ...] = ()
    scopes: tuple[int, ...] = ()
    begin: int | None = None
    end: int | None = None
    interrupt_drones: tuple[str, ...] = ()
    interrupt_mode: str | None = None
    # Inside a Try's Body: the Try that catches a failure here (see execution_graph).
    catch: int | None = None
    catch_loops: int = 0
    catch_drones: tuple[str, ...] = ()
    catch_line: int = 0  # where that Try is written
    # On a Whenever: the drones a firing suspends (see execution_graph).
    suspend_drones: tuple[str, ...] = ()
    # An action a Whenever's firing suspends; an action of a Whenever's Handler.
    suspendable: bool = False
    in_handler: bool = False
    line: int = 0
    col: int = 0
    block: str = ""

    def executed(self) -> dict[str, Any]:
        """What of this node its drone executes: every field but where it is written, and
        of a proxy (another drone's node) none of what describes it.  Equal for two nodes:
        the drone behaves the same (an amendment does not touch it)."""
        doc = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in _POSITION_FIELDS:
            del doc[name]
        if not self.native:
            for name in _PROXY_DESCRIPTIVE:
                del doc[name]
        return doc


@dataclass(frozen=True)
class ProgramArc:
    """One MDG arc; ``external`` when it crosses between drones."""

    src: str
    dst: str
    kind: str
    external: bool


@dataclass(frozen=True)
class DroneProgram:
    """The program one drone runs: its MDG and its place in the fleet."""

    mission: str
    mission_id: str
    drone: str
    drone_type: str
    fleet: tuple[str, ...]
    nodes: tuple[ProgramNode, ...]
    arcs: tuple[ProgramArc, ...]
    telemetry_from: tuple[str, ...] = ()
    source_file: str = ""
    compiler: str = ""
    # (path, sha256) of each library file the mission was built from.
    libraries: tuple[tuple[str, str], ...] = ()

    def body(self) -> dict[str, Any]:
        """The JSON document without its checksum."""
        doc: dict[str, Any] = {"format": FORMAT, "version": VERSION}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "nodes":
                value = [
                    _compact({g.name: getattr(n, g.name) for g in _NODE_FIELDS}) for n in value
                ]
            elif f.name == "arcs":
                value = [
                    {"src": a.src, "dst": a.dst, "kind": a.kind, "external": a.external}
                    for a in value
                ]
            elif f.name == "libraries":
                if not value:
                    continue  # absent: the document of a mission without libraries is unchanged
                value = [{"path": p, "sha256": h} for p, h in value]
            elif isinstance(value, tuple):
                value = list(value)
            doc[f.name] = value
        return doc

    @cached_property
    def checksum(self) -> str:
        """``sha256:<hex>`` of the canonical JSON body (computed once: programs are immutable)."""
        return "sha256:" + hashlib.sha256(_canonical(self.body())).hexdigest()

    def to_json(self) -> str:
        """The program file's text."""
        doc = self.body()
        doc["checksum"] = self.checksum
        return json.dumps(doc, indent=1, sort_keys=False) + "\n"

    def save(self, path: Path) -> Path:
        """Write the program to ``path`` (atomically: a half-written file never loads)."""
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text(self.to_json(), encoding="utf-8")
        tmp.replace(path)
        return path

    # -- views the runtime uses ---------------------------------------------

    def node(self, key: str) -> ProgramNode:
        """The node with this key."""
        for n in self.nodes:
            if n.key == key:
                return n
        raise KeyError(key)

    def native_nodes(self) -> list[ProgramNode]:
        """The nodes this drone executes."""
        return [n for n in self.nodes if n.native]

    def stats(self) -> dict[str, int]:
        """Paper Table 7's columns: nodes, internal arcs, external in/out arcs."""
        native = {n.key for n in self.nodes if n.native}
        ext_in = sum(1 for a in self.arcs if a.external and a.dst in native)
        ext_out = sum(1 for a in self.arcs if a.external and a.src in native)
        return {
            "nodes": len(self.nodes),
            "internal_arcs": sum(1 for a in self.arcs if not a.external),
            "external_in": ext_in,
            "external_out": ext_out,
        }


_NODE_FIELDS = fields(ProgramNode)


_NODE_DEFAULTS: dict[str, Any] = {
    f.name: (list(f.default) if isinstance(f.default, tuple) else f.default)
    for f in _NODE_FIELDS
    if f.default is not MISSING
}


def _compact(node: dict[str, Any]) -> dict[str, Any]:
    """Drop fields at their defaults to keep program files readable."""
    out = {}
    for key, value in node.items():
        value = list(value) if isinstance(value, tuple) else value
        if key in _NODE_DEFAULTS and value == _NODE_DEFAULTS[key]:
            continue
        out[key] = value
    return out


def _canonical(doc: dict[str, Any]) -> bytes:
    return json.dumps(doc, sort_keys=True, separators=(",", ":")).encode("utf-8")


def _require(doc: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    if key not in doc:
        raise ProgramError(f"{where}: missing field '{key}'")
    value = doc[key]
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise ProgramError(f"{where}: field '{key}' has the wrong type")
    return value


#: A number of a program: an int or a finite float (never a bool).
_NUMBER = (int, float)


def _typed(value: Any, kind: type | tuple[type, ...]) -> bool:
    if isinstance(value, bool) and kind is not bool:
        return False
    if isinstance(value, float) and not math.isfinite(value):
        return False
    return isinstance(value, kind)


def _opt(raw: dict[str, Any], key: str, kind: type, at: str, default: Any) -> Any:
    """An optional field of ``kind`` (``default`` when absent or null)."""
    value = raw.get(key)
    if value is None:
        return default
    if not _typed(value, kind):
        raise ProgramError(f"{at}: field '{key}' has the wrong type")
    return value


def _list(raw: dict[str, Any], key: str, kind: type | tuple[type, ...], at: str) -> list[Any]:
    """An optional list field whose items are all of ``kind`` (empty when absent)."""
    value = raw.get(key, [])
    if not isinstance(value, list) or not all(_typed(item, kind) for item in value):
        raise ProgramError(f"{at}: field '{key}' has the wrong type")
    return value


def program_from_dict(doc: Any, where: str = "program") -> DroneProgram:
    """Validate a decoded program document and build the :class:`DroneProgram`."""
    if not isinstance(doc, dict):
        raise ProgramError(f"{where}: not a program document")
    if doc.get("format") != FORMAT:
        raise ProgramError(f"{where}: not an EAMOS drone program (format is {doc.get('format')!r})")
    version = doc.get("version")
    if version != VERSION:
        raise ProgramError(
            f"{where}: program version {version!r} is not supported "
            f"(this eamos reads version {VERSION}); recompile the mission"
        )
    checksum = _require(doc, "checksum", str, where)
    body = {k: v for k, v in doc.items() if k != "checksum"}
    actual = "sha256:" + hashlib.sha256(_canonical(body)).hexdigest()
    if checksum != actual:
        raise ProgramError(
            f"{where}: checksum mismatch: the file was changed or damaged; "
            "recompile and redeploy it"
        )
    nodes = []
    for i, raw in enumerate(_require(doc, "nodes", list, where)):
        at = f"{where}: nodes[{i}]"
        if not isinstance(raw, dict):
            raise ProgramError(f"{at}: not an object")
        kind = _require(raw, "kind", str, at)
        if kind not in NODE_KINDS:
            raise ProgramError(f"{at}: unknown node kind {kind!r}")
        cond = raw.get("cond")
        if cond is not None:
            try:
                validate(cond)
            except ConditionError as exc:
                raise ProgramError(f"{at}: bad condition: {exc}") from exc
        try:
            nodes.append(
                ProgramNode(
                    key=_require(raw, "key", str, at),
                    meg=_require(raw, "meg", int, at),
                    kind=kind,
                    drone=_require(raw, "drone", str, at),
                    native=_require(raw, "native", bool, at),
                    label=_opt(raw, "label", str, at, ""),
                    action=_opt(raw, "action", str, at, None),
                    args=tuple(float(a) for a in _list(raw, "args", _NUMBER, at)),
                    cond=cond,
                    count=_opt(raw, "count", int, at, None),
                    loops=tuple(_list(raw, "loops", int, at)),
                    scopes=tuple(_list(raw, "scopes", int, at)),
                    begin=_opt(raw, "begin", int, at, None),
                    end=_opt(raw, "end", int, at, None),
                    interrupt_drones=tuple(_list(raw, "interrupt_drones", str, at)),
                    interrupt_mode=_opt(raw, "interrupt_mode", str, at, None),
                    catch=_opt(raw, "catch", int, at, None),
                    catch_loops=_opt(raw, "catch_loops", int, at, 0),
                    catch_drones=tuple(_list(raw, "catch_drones", str, at)),
                    catch_line=_opt(raw, "catch_line", int, at, 0),
                    suspend_drones=tuple(_list(raw, "suspend_drones", str, at)),
                    suspendable=_opt(raw, "suspendable", bool, at, False),
                    in_handler=_opt(raw, "in_handler", bool, at, False),
                    line=_opt(raw, "line", int, at, 0),
                    col=_opt(raw, "col", int, at, 0),
                    block=_opt(raw, "block", str, at, ""),
                )
            )
        except (TypeError, ValueError) as exc:
            raise ProgramError(f"{at}: {exc}") from exc
    keys = {n.key for n in nodes}
    if len(keys) != len(nodes):
        raise ProgramError(f"{where}: duplicate node keys")
    arcs = []
    for i, raw in enumerate(_require(doc, "arcs", list, where)):
        at = f"{where}: arcs[{i}]"
        if not isinstance(raw, dict):
            raise ProgramError(f"{at}: not an object")
        arc = ProgramArc(
            _require(raw, "src", str, at),
            _require(raw, "dst", str, at),
            _require(raw, "kind", str, at),
            _require(raw, "external", bool, at),
        )
        if arc.src not in keys or arc.dst not in keys:
            raise ProgramError(f"{at}: refers to a node that is not in the program")
        if arc.kind not in ARC_KINDS:
            raise ProgramError(f"{at}: unknown arc kind {arc.kind!r}")
        arcs.append(arc)
    return DroneProgram(
        mission=_require(doc, "mission", str, where),
        mission_id=_require(doc, "mission_id", str, where),
        drone=_require(doc, "drone", str, where),
        drone_type=_require(doc, "drone_type", str, where),
        fleet=_names(_require(doc, "fleet", list, where), "fleet", where),
        nodes=tuple(nodes),
        arcs=tuple(arcs),
        telemetry_from=_names(doc.get("telemetry_from", []), "telemetry_from", where),
        source_file=str(doc.get("source_file", "")),
        compiler=str(doc.get("compiler", "")),
        libraries=_libraries(doc.get("libraries", []), where),
    )


def _names(names: Any, key: str, where: str) -> tuple[str, ...]:
    """The list of participant names in field ``key``, as a tuple."""
    if not isinstance(names, list) or not all(isinstance(name, str) for name in names):
        raise ProgramError(f"{where}: field '{key}' holds something other than names")
    return tuple(names)


def _libraries(raw: Any, where: str) -> tuple[tuple[str, str], ...]:
    """The optional ``libraries`` list: ``{"path", "sha256"}`` objects."""
    if not isinstance(raw, list):
        raise ProgramError(f"{where}: field 'libraries' has the wrong type")
    out = []
    for i, item in enumerate(raw):
        at = f"{where}: libraries[{i}]"
        if not isinstance(item, dict):
            raise ProgramError(f"{at}: not an object")
        out.append((_require(item, "path", str, at), _require(item, "sha256", str, at)))
    return tuple(out)


#: Largest program file read (a mission at the compiler's caps makes far smaller ones).
MAX_PROGRAM_BYTES = 256 << 20
#: Deepest nesting of a program document: a condition nests at most
#: :data:`~eamos.program.conditions.MAX_DEPTH` operators, inside a node, inside the list.
MAX_PROGRAM_DEPTH = MAX_CONDITION_DEPTH + 8


def load_program(path: Path) -> DroneProgram:
    """Load and verify a program file; raise :class:`ProgramError` with the reason.

    Bounded before anything recurses: at most :data:`MAX_PROGRAM_BYTES` are read and
    the document may nest at most :data:`MAX_PROGRAM_DEPTH` deep (a file of 100 000
    nested arrays is damaged, not a crash).
    """
    try:
        with Path(path).open("rb") as file:
            data = file.read(MAX_PROGRAM_BYTES + 1)
    except FileNotFoundError as exc:
        raise ProgramError(f"{path}: no such program file") from exc
    except (OSError, ValueError) as exc:
        raise ProgramError(f"{path}: cannot read the program: {exc}") from exc
    return program_from_bytes(data, str(path))


def program_from_bytes(data: bytes, where: str = "program") -> DroneProgram:
    """A program file's bytes, verified as :func:`load_program` verifies a file (``where``
    names them in errors): the bytes of an amended program sent to a flying drone."""
    if len(data) > MAX_PROGRAM_BYTES:
        raise ProgramError(f"{where}: over {MAX_PROGRAM_BYTES} bytes: not a program file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ProgramError(f"{where}: cannot read the program: {exc}") from exc
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ProgramError(
            f"{where}: not valid JSON (line {exc.lineno}): the file is damaged"
        ) from exc
    except RecursionError as exc:
        raise ProgramError(
            f"{where}: nested more than {MAX_PROGRAM_DEPTH} deep: the file is damaged"
        ) from exc
    _check_depth(doc, where)
    return program_from_dict(doc, where)


def _check_depth(doc: Any, where: str) -> None:
    """Refuse a document nested deeper than :data:`MAX_PROGRAM_DEPTH` (iterative)."""
    todo: list[tuple[Any, int]] = [(doc, 0)]
    while todo:
        value, depth = todo.pop()
        if isinstance(value, dict | list) and value:
            if depth >= MAX_PROGRAM_DEPTH:
                raise ProgramError(
                    f"{where}: nested more than {MAX_PROGRAM_DEPTH} deep: the file is damaged"
                )
            items = value.values() if isinstance(value, dict) else value
            todo.extend((item, depth + 1) for item in items)
