"""The drone runtime's one exception type (the command line turns it into an exit code)."""

from __future__ import annotations

__all__ = ["DroneRuntimeError"]


class DroneRuntimeError(Exception):
    """A drone runtime cannot start or run (bad program, adapter unusable, network)."""
