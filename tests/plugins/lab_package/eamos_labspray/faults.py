"""A lab's broken plugins, for the tests of what a plugin cannot do to a vehicle.

Declarations and "sim" implementations in one module (the implementations import
nothing of EAMOS, so the compiler may load it).  Each implementation misbehaves as
its name says: it exits the interpreter, raises Ctrl-C's exception, sleeps forever,
or spins forever.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, NoReturn

from eamos.program.plugins import ActionPlugin

if TYPE_CHECKING:
    from eamos.hal.sim.plugin_api import SimView
    from eamos.program.uniform import PluginAction


def _declared(name: str, doc: str, function: str) -> ActionPlugin:
    return ActionPlugin(
        name=name, params=(), doc=doc, implementations={"sim": f"eamos_labspray.faults:{function}"}
    )


QUIT = _declared("Quit", "Calls sys.exit(3) in its sim implementation.", "quit_")
CTRL_C = _declared("CtrlC", "Raises KeyboardInterrupt in its sim implementation.", "ctrl_c")
STALL = _declared("Stall", "Sleeps forever in its sim implementation.", "stall")
SPIN = _declared("Spin", "Spins forever in its sim implementation.", "spin")


def quit_(view: SimView, command: PluginAction) -> NoReturn:
    raise SystemExit(3)


def ctrl_c(view: SimView, command: PluginAction) -> NoReturn:
    raise KeyboardInterrupt


def stall(view: SimView, command: PluginAction) -> NoReturn:
    threading.Event().wait()
    raise AssertionError("never set")


def spin(view: SimView, command: PluginAction) -> NoReturn:
    while True:
        pass
