"""The exit codes of every EAMOS command (documented in the README).

One table for all console entry points, so that a script driving ``eamos``,
``eamos-node`` or ``eamos-sim-vehicle`` reads the same number for the same
outcome.
"""

from __future__ import annotations

#: Everything asked for was done (the mission finished with every drone ok).
EXIT_OK = 0
#: The mission ran and failed (an action failed, a drone was lost, the run was aborted).
EXIT_MISSION_FAILED = 1
#: Bad input: a mission with errors, a bad config or fleet file, a bad run folder or argument.
EXIT_BAD_INPUT = 2
#: Could not connect: peers, vehicles, SSH targets or a port that is unreachable or taken.
EXIT_CONNECT = 3
#: An internal error (a bug in EAMOS); the traceback is printed with ``-v``.
EXIT_INTERNAL = 4

#: Ctrl-C before a command had anything to clean up (the shell's 128 + SIGINT); not
#: an outcome of the table: a running mission turns Ctrl-C into an abort (1).
EXIT_INTERRUPTED = 130

EXIT_CODES: dict[int, str] = {
    EXIT_OK: "ok",
    EXIT_MISSION_FAILED: "mission failed",
    EXIT_BAD_INPUT: "bad input",
    EXIT_CONNECT: "could not connect",
    EXIT_INTERNAL: "internal error",
}
