"""Node logic as pure transitions: one small class per node kind, returning effects.

Public names: :class:`NodeLogic` and the kinds (:class:`PassThrough`,
:class:`ActionLogic`, :class:`IfLogic`, :class:`WaitLogic`, :class:`LoopLogic`,
:class:`DoLogic`, :class:`DoEndLogic`), :func:`node_logic`, :func:`program_wiring`,
:class:`NodeWiring`, :class:`Route`, and the effects (:mod:`.effects`).  No
pykka, no threads, no clocks: the actor (:mod:`eamos.actors.node`) and the
virtual-time driver (:mod:`eamos.virtual`) are the hosts that apply effects.
"""

from .base import ActionLogic, NodeLogic, PassThrough
from .conditions import ConditionLogic, DoEndLogic, DoLogic, IfLogic, WaitLogic
from .effects import (
    Broadcast,
    CancelAction,
    Effect,
    Emit,
    Note,
    Progress,
    Record,
    ReleaseBegin,
    Resolve,
    Route,
    StartAction,
    UnwatchTelemetry,
    WatchTelemetry,
)
from .kinds import (
    CONDITION_KINDS,
    DO_KINDS,
    LOOP_KINDS,
    WAIT_KINDS,
    NodeWiring,
    logic_class,
    node_logic,
    program_wiring,
)
from .loops import LoopLogic, LoopState

__all__ = [
    "CONDITION_KINDS",
    "DO_KINDS",
    "LOOP_KINDS",
    "WAIT_KINDS",
    "ActionLogic",
    "Broadcast",
    "CancelAction",
    "ConditionLogic",
    "DoEndLogic",
    "DoLogic",
    "Effect",
    "Emit",
    "IfLogic",
    "LoopLogic",
    "LoopState",
    "NodeLogic",
    "NodeWiring",
    "Note",
    "PassThrough",
    "Progress",
    "Record",
    "ReleaseBegin",
    "Resolve",
    "Route",
    "StartAction",
    "UnwatchTelemetry",
    "WaitLogic",
    "WatchTelemetry",
    "logic_class",
    "node_logic",
    "program_wiring",
]
