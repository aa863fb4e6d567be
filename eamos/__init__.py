"""EAMOS: multi-drone missions as short Go-syntax text, compiled per drone, run decentralized.

Packages: :mod:`eamos.compiler` (mission text to drone programs),
:mod:`eamos.program` (the program format drones load), :mod:`eamos.actors`
(the drone execution environment), :mod:`eamos.net` (in- and out-bridges),
:mod:`eamos.hal` (uniform API and adapters).
"""

__version__ = "0.1.0"
