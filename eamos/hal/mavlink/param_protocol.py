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

    def set_all(
        self,
        writes: list[tuple[str, float, int]],
        *,
        timeout_s: float,
        retries: int,
        abandon: Callable[[], bool] = lambda: False,
    ) -> dict[str, tuple[float, int]]:
        """Set several parameters as one burst: every PARAM_SET of ``writes`` (name, raw
        wire value, MAV_PARAM_TYPE) is sent, in order, before any echo is awaited; those
        not echoed within ``timeout_s`` are sent again, ``retries`` tries in all.  The
        (raw value, type) each echo carried, by name; a name never echoed is absent.

        Why a burst: PX4 saves its parameters 300 ms after the first change, then reads
        the file back and compares it with the live values.  A PARAM_SET that lands
        between the write and the read-back fails that check, and PX4 SITL has been seen
        to stall in the retry that follows.  Writes sent one echo at a time at a
        simulator speed-up of 5 span more than 300 ms of vehicle time; a burst lands
        before the save begins.
        """
        link = self.link
        answers: dict[str, tuple[float, int]] = {}
        pending = list(writes)
        for _ in range(retries):
            if not pending:
                break
            with link.cond:
                seen = link.state.param_serial
            system, component = link.target
            for name, raw, param_type in pending:
                link.send("param_set", system, component, name.encode(), raw, param_type)

            def echoed(name: str, seen: int = seen) -> bool:
                entry = link.state.params.get(name)
                return entry is not None and entry[2] > seen

            def all_echoed(pending: list[tuple[str, float, int]] = pending) -> bool:
                return abandon() or link.state.closed or all(echoed(name) for name, _, _ in pending)

            with link.cond:
                link.cond.wait_for(all_echoed, timeout=timeout_s)
                for name, _, _ in pending:
                    if echoed(name):
                        entry = link.state.params[name]
                        answers[name] = (entry[0], entry[1])
                if abandon() or link.state.closed:
                    break
            pending = [w for w in pending if w[0] not in answers]
        return answers


__all__ = ["ParamProtocol"]
