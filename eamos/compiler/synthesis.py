"""Phase 6: Mission Dependency Graph -> drone mission program (paper Section V-D).

The paper synthesised Go source per drone; we ship the MDG itself as a
versioned, checksummed JSON document (:mod:`eamos.program.format`) that the
runtime loads without the compiler.
"""

from __future__ import annotations

from typing import Any

import networkx as nx

from .. import __version__
from ..program.conditions import properties
from ..program.format import DroneProgram, ProgramArc, ProgramNode
from ..program.uniform import GROUND_STATION, GROUND_TYPE


def _node(key: str, attrs: dict[str, Any]) -> ProgramNode:
    def tup(name: str) -> tuple[Any, ...]:
        return tuple(attrs.get(name) or ())

    return ProgramNode(
        key=key,
        meg=int(attrs["meg"]),
        kind=str(attrs["kind"]),
        drone=str(attrs["drone"]),
        native=bool(attrs["native"]),
        label=str(attrs.get("label", "")),
        action=attrs.get("action"),
        args=tuple(float(a) for a in tup("args")),
        cond=attrs.get("cond"),
        count=attrs.get("count"),
        loops=tup("loops"),
        scopes=tup("scopes"),
        begin=attrs.get("begin"),
        end=attrs.get("end"),
        interrupt_drones=tup("interrupt_drones"),
        interrupt_mode=attrs.get("interrupt_mode"),
        catch=attrs.get("catch"),
        catch_loops=int(attrs.get("catch_loops", 0)),
        catch_drones=tup("catch_drones"),
        catch_line=int(attrs.get("catch_line", 0)),
        suspend_drones=tup("suspend_drones"),
        suspendable=bool(attrs.get("suspendable", False)),
        in_handler=bool(attrs.get("in_handler", False)),
        line=int(attrs.get("line", 0)),
        col=int(attrs.get("col", 0)),
        block=str(attrs.get("block", "")),
    )


def synthesize_program(
    mdg: nx.DiGraph,
    *,
    mission_id: str,
    fleet: list[str],
    drone_type: str,
    source_file: str = "",
    libraries: tuple[tuple[str, str], ...] = (),
) -> DroneProgram:
    """Turn one drone's MDG into its drone mission program."""
    drone = mdg.graph["drone"]
    nodes = tuple(
        _node(k, a) for k, a in sorted(mdg.nodes(data=True), key=lambda kv: (kv[1]["meg"], kv[0]))
    )
    arcs = tuple(
        ProgramArc(a, b, d["kind"], bool(d["external"]))
        for a, b, d in sorted(
            mdg.edges(data=True),
            key=lambda e: (mdg.nodes[e[0]]["meg"], mdg.nodes[e[1]]["meg"], e[0], e[1]),
        )
    )
    reads = sorted(
        {d for n in nodes if n.native and n.cond is not None for d, _ in properties(n.cond)}
        - {drone}
    )
    return DroneProgram(
        mission=str(mdg.graph.get("mission", "mission")),
        mission_id=mission_id,
        drone=drone,
        drone_type=GROUND_TYPE.name if drone == GROUND_STATION else drone_type,
        fleet=tuple(fleet),
        nodes=nodes,
        arcs=arcs,
        telemetry_from=tuple(reads),
        source_file=source_file,
        compiler=__version__,
        libraries=libraries,
    )
