"""The MAVLink command protocol: COMMAND_LONG (or COMMAND_INT) until its COMMAND_ACK.

https://mavlink.io/en/services/command.html: a command is sent again when no ack comes
(``confirmation`` counts the tries), and MAV_RESULT_IN_PROGRESS extends the wait.  The
ack is read from the link's state (:attr:`~eamos.hal.mavlink.state.LinkState.ack_serial`),
waiting on the link's condition: nothing polls.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from eamos.hal.mavlink.link import MavlinkLink

#: MAV_RESULT values the adapter tells apart (names: :data:`~.state.MAV_RESULT_NAMES`).
MAV_RESULT_ACCEPTED = 0
MAV_RESULT_TEMPORARILY_REJECTED = 1
MAV_RESULT_IN_PROGRESS = 5


class CommandProtocol:
    """Commands to the vehicle on one link, each answered by the MAV_RESULT of its ack."""

    def __init__(self, link: MavlinkLink) -> None:
        self.link = link

    def request(
        self,
        command: int,
        params: tuple[float, ...],
        *,
        timeout_s: float,
        retries: int,
        abandon: Callable[[], bool] = lambda: False,
        frame: int | None = None,
    ) -> int | None:
        """Send COMMAND_LONG and return the MAV_RESULT of its COMMAND_ACK.

        With ``frame`` it is sent as COMMAND_INT in that MAV_FRAME instead: params 5
        and 6 (x, y: latitude and longitude in degrees) travel as degrees * 1e7, so a
        position keeps its centimetres (COMMAND_LONG's float32 loses ~0.4 m).

        Tries ``retries`` times, waiting ``timeout_s`` for an ack each time
        (``confirmation`` counts the tries, as the protocol asks).  Returns
        None when no ack came, or early when ``abandon()`` (evaluated under
        the condition) turns true.  MAV_RESULT_IN_PROGRESS extends the wait.
        """
        link = self.link
        if len(params) != 7:
            raise ValueError("COMMAND_LONG takes 7 params")
        for attempt in range(retries):
            with link.cond:
                seen = link.state.ack_serial
            system, component = link.target
            if frame is None:
                link.send("command_long", system, component, command, attempt, *params)
            else:
                p = params
                link.send(
                    "command_int",
                    system,
                    component,
                    frame,
                    command,
                    0,  # current
                    0,  # autocontinue
                    *p[:4],
                    round(p[4] * 1e7),
                    round(p[5] * 1e7),
                    p[6],
                )
            deadline = time.monotonic() + timeout_s
            while True:
                with link.cond:

                    def answered(seen: int = seen) -> bool:
                        return (
                            abandon()
                            or link.state.closed
                            or link.state.ack_since(command, seen) is not None
                        )

                    link.cond.wait_for(answered, timeout=max(0.0, deadline - time.monotonic()))
                    result = link.state.ack_since(command, seen)
                    if result is None:
                        if abandon() or link.state.closed:
                            return None
                        break  # no ack: try again
                    if result != MAV_RESULT_IN_PROGRESS:
                        return result
                    seen = link.state.ack_serial
                    deadline = time.monotonic() + timeout_s
        return None


__all__ = [
    "MAV_RESULT_ACCEPTED",
    "MAV_RESULT_IN_PROGRESS",
    "MAV_RESULT_TEMPORARILY_REJECTED",
    "CommandProtocol",
]
