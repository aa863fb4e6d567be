"""What a drone runtime does when one of its own parts raises (issue 9's failure policy).

Node actors handle their own failures (a node resolves ``failed``; see
:mod:`.node`).  The other parts -- the telemetry board, the executive, the
in-bridge callback -- hold state every node relies on (watched values,
resolutions, interrupts), so after an exception in one of them nothing about
the rest of the mission on this drone is safe: the runtime aborts the drone (it
lands through the uniform API), releases the drones waiting for it, and tells
the ground station at once.  :class:`FailurePolicy` logs every exception once,
with its traceback, in the mission log, and runs that reaction once.
"""

from __future__ import annotations

import sys
import threading
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, ClassVar

from .dispatch import PooledActor
from .pykka_seam import ExcInfo

if TYPE_CHECKING:
    from ..logs import EventLog

__all__ = ["FailurePolicy", "FailureSink", "RuntimeFailure", "RuntimePart", "tell_operator"]

#: Where a runtime part reports an exception: ``sink(part, exception)``.
FailureSink = Callable[[str, BaseException], None]


def tell_operator(drone: str, text: str) -> None:
    """One line on stderr (a node's ``node.out``) for something the operator must see.

    Never raises: stderr may be a file on a full disk, and a failure report
    must not become a second failure.
    """
    try:
        print(f"eamos-node {drone}: {text} (details in mission.log)", file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


@dataclass(frozen=True)
class RuntimeFailure:
    """One exception in a part of a drone runtime."""

    part: str  # "executive", "telemetry board", "in-bridge"
    error: str  # repr of the exception
    traceback: str

    def reason(self) -> str:
        """Why the drone aborted, as the report and the ground station show it."""
        return f"internal error in the {self.part}: {self.error}"


class FailurePolicy:
    """Log each exception once; run ``react`` for the first one (thread-safe)."""

    def __init__(
        self, log: EventLog, react: Callable[[RuntimeFailure], None], drone: str = "drone"
    ) -> None:
        self._log = log
        self.drone = drone
        self._react = react
        self._lock = threading.Lock()
        self.failures: list[RuntimeFailure] = []

    def __call__(self, part: str, exc: BaseException) -> None:
        """Called by the part that raised, on its own thread, with the exception."""
        failure = RuntimeFailure(
            part, repr(exc), "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
        )
        with self._lock:
            first = not self.failures
            self.failures.append(failure)
        self._log.error(
            "mission.failure", part=part, error=failure.error, traceback=failure.traceback
        )
        if first:
            tell_operator(self.drone, failure.reason() + ": the drone aborts and lands")
            self._react(failure)

    def on_actor_exit(self, actor: PooledActor, exc: BaseException) -> None:
        """A drone dispatcher's exit hook (:data:`~.dispatch.ExitHook`): a ``BaseException``
        ended a handler of one of the drone's actors, after the actor's own policy (a node
        resolved ``failed``).  It is a failure of the drone, which aborts; the process and
        the other drones in it go on."""
        key = getattr(actor, "key", None)  # a mission node's
        self(f"node {key}" if key is not None else type(actor).__name__, exc)

    @property
    def first(self) -> RuntimeFailure | None:
        """The failure the drone aborted for (None: none happened)."""
        with self._lock:
            return self.failures[0] if self.failures else None


class RuntimePart(PooledActor):
    """A runtime part (board, executive) whose exceptions go to the drone's failure policy.

    The part stays alive after reporting, so the drone's report can still be
    built; without a sink (a part built alone in a test) Pykka's default applies.
    """

    #: The part's name in ``mission.failure`` lines.
    part: ClassVar[str] = "runtime part"
    failure: FailureSink | None = None

    def on_failure(
        self,
        exception_type: type[BaseException] | None,
        exception_value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        """Tell the runtime's failure policy (it aborts the drone); stay alive for the report."""
        if self.failure is None or exception_value is None:
            super().on_failure(exception_type, exception_value, traceback)
        else:
            self.failure(self.part, exception_value)

    def exited(self, exc_info: ExcInfo) -> None:
        """A ``BaseException`` (``SystemExit``, ...) in a handler: as an exception, the
        failure policy aborts the drone (which is all the dispatcher's hook would do)."""
        if self.failure is None:
            super().exited(exc_info)
        else:
            self.failed(exc_info)
