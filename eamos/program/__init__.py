"""The program layer: the mission vocabulary and the drone program format (standard library only).

Everything the compiler produces and a drone loads, with nothing but the standard
library (a drone needs neither the compiler nor tree-sitter):

* the uniform API's vocabulary (:mod:`.uniform`): :data:`ACTIONS` (each an
  :class:`ActionSpec`, parameters with units), :data:`PROPERTIES`,
  :data:`CONTROL_STRUCTURES`, the drone types (:data:`DRONE_TYPES`, :class:`DroneType`,
  :data:`DEFAULT_DRONE_TYPE`, :data:`GROUND_TYPE`), the ground station's name
  :data:`GROUND_STATION`, and typed commands (:class:`Command` and its kinds,
  :func:`decode_command`, :class:`CommandError`, :class:`PluginAction`);
* conditions as data (:mod:`.conditions`): :data:`Condition`, :func:`evaluate`,
  :class:`Unknown`, :class:`ConditionError` (checking and printing them:
  ``validate``, ``to_text``, ``properties`` there);
* the program file (:mod:`.format`): :class:`DroneProgram` with its
  :class:`ProgramNode` and :class:`ProgramArc` (:data:`NODE_KINDS`),
  :func:`load_program`, :func:`program_from_dict`, :class:`ProgramError`;
* action plugins (:mod:`.plugins`, docs/plugins.md): :class:`ActionPlugin`,
  :class:`PluginRegistry` (:data:`EMPTY_PLUGINS`, :func:`discover_plugins`),
  :class:`PluginError`, :data:`ENTRY_POINT_GROUP`, :data:`FAMILIES`; the project's own
  camera actions are such plugins (:mod:`.camera`, :data:`CAMERA_PLUGINS`).
"""

from .camera import CAMERA_PLUGINS
from .conditions import Condition, ConditionError, Unknown, evaluate
from .format import (
    NODE_KINDS,
    DroneProgram,
    ProgramArc,
    ProgramError,
    ProgramNode,
    load_program,
    program_from_dict,
)
from .plugins import (
    EMPTY_PLUGINS,
    ENTRY_POINT_GROUP,
    FAMILIES,
    ActionPlugin,
    PluginError,
    PluginRegistry,
    discover_plugins,
)
from .uniform import (
    ACTIONS,
    CONTROL_STRUCTURES,
    DEFAULT_DRONE_TYPE,
    DRONE_TYPES,
    GROUND_STATION,
    GROUND_TYPE,
    PROPERTIES,
    ActionSpec,
    Command,
    CommandError,
    DroneType,
    PluginAction,
    decode_command,
)

__all__ = [
    "ACTIONS",
    "CAMERA_PLUGINS",
    "CONTROL_STRUCTURES",
    "DEFAULT_DRONE_TYPE",
    "DRONE_TYPES",
    "EMPTY_PLUGINS",
    "ENTRY_POINT_GROUP",
    "FAMILIES",
    "GROUND_STATION",
    "GROUND_TYPE",
    "NODE_KINDS",
    "PROPERTIES",
    "ActionPlugin",
    "ActionSpec",
    "Command",
    "CommandError",
    "Condition",
    "ConditionError",
    "DroneProgram",
    "DroneType",
    "PluginAction",
    "PluginError",
    "PluginRegistry",
    "ProgramArc",
    "ProgramError",
    "ProgramNode",
    "Unknown",
    "decode_command",
    "discover_plugins",
    "evaluate",
    "load_program",
    "program_from_dict",
]
