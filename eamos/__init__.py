"""EAMOS: multi-drone missions as short Go-syntax text, compiled per drone, run decentralized.

Packages: :mod:`eamos.compiler` (mission text to drone programs),
:mod:`eamos.program` (the vocabulary and the program format drones load),
:mod:`eamos.actors` (the drone execution environment), :mod:`eamos.net` (in- and
out-bridges), :mod:`eamos.hal` (uniform API and adapters), :mod:`eamos.ground` (the
ground station); the map of all of them is docs/architecture.md.  This package itself
offers only the version.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
