"""Node logic as pure transitions: one small class per node kind, returning effects.

Public names: :class:`NodeLogic` and the kinds (:class:`PassThrough`,
:class:`ActionLogic`, :class:`IfLogic`, :class:`WaitLogic`, :class:`LoopLogic`,
:class:`DoLogic`, :class:`DoEndLogic`, :class:`TryEndLogic`,
:class:`WheneverLogic`, :class:`WheneverEndLogic`, :class:`AbandonLogic`),
:func:`node_logic`, :func:`program_wiring`, :class:`NodeWiring`,
:class:`Route`, and the effects (:mod:`.effects`).  No pykka, no threads, no
clocks: the actor (:mod:`eamos.actors.node`) and the virtual-time driver
(:mod:`eamos.virtual`) are the hosts that apply effects.
"""

from .actions import ActionLogic
from .base import NodeLogic, PassThrough
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
from .events import AbandonLogic, WheneverEndLogic, WheneverLogic
from .handlers import TryEndLogic
from .kinds import (
    CONDITION_KINDS,
    DO_KINDS,
    LOOP_KINDS,
    TRY_KINDS,
    WAIT_KINDS,
    WHENEVER_KINDS,
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
    "TRY_KINDS",
    "WAIT_KINDS",
    "WHENEVER_KINDS",
    "AbandonLogic",
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
    "TryEndLogic",
    "UnwatchTelemetry",
    "WaitLogic",
    "WatchTelemetry",
    "WheneverEndLogic",
    "WheneverLogic",
    "logic_class",
    "node_logic",
    "program_wiring",
]
