"""The MAVLink parameter protocol: PARAM_REQUEST_READ or PARAM_SET, answered by PARAM_VALUE.

https://mavlink.io/en/services/parameter.html: a read or a write is sent again when no
PARAM_VALUE for that name comes; the answer is read from the link's state
(:attr:`~eamos.hal.mavlink.state.LinkState.params`), waiting on the link's condition.
What to set, and the wire encoding of a value, are :mod:`eamos.hal.mavlink.params`'.
"""

from __future__ import annotations

from collections.abc import Callable

from eamos.hal.mavlink.link import MavlinkLink


class ParamProtocol:
    """Reading and setting one vehicle's parameters on one link."""

    def __init__(self, link: MavlinkLink) -> None:
        self.link = link

    def request(
        self,
        name: str,
        write: tuple[float, int] | None,
        *,
        timeout_s: float,
        retries: int,
        abandon: Callable[[], bool] = lambda: False,
    ) -> tuple[float, int] | None:
        """Read a parameter (``write`` None: PARAM_REQUEST_READ) or set it (PARAM_SET with
        ``(raw wire value, MAV_PARAM_TYPE)``); the (raw value, type) of the PARAM_VALUE
        that answers, or None when none came after ``retries`` tries."""
        link = self.link
        encoded = name.encode()
        for _ in range(retries):
            with link.cond:
                seen = link.state.param_serial
            system, component = link.target
            if write is None:
                link.send("param_request_read", system, component, encoded, -1)
            else:
                link.send("param_set", system, component, encoded, write[0], write[1])

            def answered(seen: int = seen) -> bool:
                entry = link.state.params.get(name)
                return abandon() or link.state.closed or (entry is not None and entry[2] > seen)

            with link.cond:
                link.cond.wait_for(answered, timeout=timeout_s)
                entry = link.state.params.get(name)
                if entry is not None and entry[2] > seen:
                    return entry[0], entry[1]
                if abandon() or link.state.closed:
                    return None
        return None


__all__ = ["ParamProtocol"]
