"""A lab's action plugin, as docs/plugins.md describes it: ``Spray(duration_s)``.

This module is what the entry point names: it holds only the declaration (the compiler
loads it), and names the simulator implementation by string (imported by the adapter).
"""

from eamos.program.plugins import ActionPlugin

SPRAY = ActionPlugin(
    name="Spray",
    params=("duration_s",),
    doc="Spray the crop below for `duration_s` seconds.",
    implementations={"sim": "eamos_labspray.sim:spray"},
    ranges={"duration_s": (0.0, 60.0)},
)
