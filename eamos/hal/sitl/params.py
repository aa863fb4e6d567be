"""The simulated vehicle's parameters: PARAM_REQUEST_LIST/READ and PARAM_SET.

Each autopilot's parameter names, defaults and wire encoding come from its
personality (:mod:`eamos.hal.sitl.px4`, :mod:`eamos.hal.sitl.ardupilot`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from eamos.hal.sitl.streams import Send

if TYPE_CHECKING:
    from eamos.logs import EventLog

#: A parameter: its value and MAV_PARAM_TYPE.
Param = tuple[float, int]
Params = dict[str, Param]


class WireEncoding(Protocol):
    """How a personality carries parameter values in PARAM_VALUE / PARAM_SET."""

    def param_to_wire(self, value: float, ptype: int) -> float:
        """A parameter's value as PARAM_VALUE carries it."""
        ...

    def param_from_wire(self, raw: float, ptype: int) -> float:
        """A PARAM_SET value as the parameter's value."""
        ...


class ParamTable:
    """The vehicle's parameters: PARAM_REQUEST_LIST/READ and PARAM_SET, each answered with
    PARAM_VALUE in the personality's wire encoding."""

    def __init__(
        self, personality: WireEncoding, initial: Params, log: EventLog, send: Send
    ) -> None:
        self._p = personality
        self._params: Params = dict(initial)
        self._log = log
        self._send = send

    def value(self, name: str) -> float:
        """A parameter's current value."""
        return self._params[name][0]

    def snapshot(self) -> Params:
        """A copy of every parameter."""
        return dict(self._params)

    def send_all(self) -> None:
        """PARAM_REQUEST_LIST: every parameter, in order."""
        for index, name in enumerate(self._params):
            self._send_param(name, index)

    def read(self, name: str, index: int) -> None:
        """PARAM_REQUEST_READ by index (if valid) or name; unknown ones stay unanswered."""
        names = list(self._params)
        if 0 <= index < len(names):
            name = names[index]
        if name in self._params:
            self._send_param(name, names.index(name))

    def set(self, name: str, raw: float) -> None:
        """PARAM_SET: store and echo; both SITLs stay silent about unknown parameters."""
        if name not in self._params:
            return
        _, ptype = self._params[name]
        value = self._p.param_from_wire(raw, ptype)
        self._params[name] = (value, ptype)
        self._log.info("vehicle.param", name=name, value=value)
        self._send_param(name, list(self._params).index(name))

    def _send_param(self, name: str, index: int) -> None:
        value, ptype = self._params[name]
        wire = self._p.param_to_wire(value, ptype)
        self._send("param_value", name.encode(), wire, ptype, len(self._params), index)


__all__ = ["Param", "ParamTable", "Params", "WireEncoding"]
