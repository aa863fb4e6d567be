"""The wire format's limits, its one error type and its field validators.

Split from :mod:`eamos.net.wire` (which re-exports the public names): every
message field names one validator here, run when a message is constructed (so
a bad message fails at the sender) and again when it is decoded.
"""

from __future__ import annotations

from typing import Any, Final

# Limits applied before and during unpacking so a hostile or broken peer cannot
# make a receiver allocate without bound.  Reports are the largest legitimate
# messages and stay far below this.
MAX_PAYLOAD_BYTES: Final = 1 << 20
MAX_TOPIC_BYTES: Final = 256
MAX_DEPTH: Final = 32
_MAX_CONTAINER_LEN: Final = 1 << 16
REPORT_PART_BYTES: Final = 256 * 1024
"""Bytes of a report's encoding one ReportPart carries (at most); a quarter of a message."""
MAX_REPORT_PARTS: Final = 256
"""At most this many parts make one report (64 MiB): a receiver's bound on what it joins."""


class WireError(ValueError):
    """A message could not be encoded or decoded (the network layer's one error type).

    ``reason`` is ``"version"`` when the payload is of another wire version,
    ``"oversize"`` for a payload over :data:`MAX_PAYLOAD_BYTES` and ``"malformed"``
    for everything else; receivers log and count drops by it.
    """

    def __init__(self, message: str, reason: str = "malformed") -> None:
        super().__init__(message)
        self.reason = reason


# ---------------------------------------------------------------------------
# Field kinds: one validator per kind, used both when a message is constructed
# (so a bad message fails at the sender, not at the receiver) and when decoded.


def _check_name(value: Any, name: str) -> str:
    # Participant names end up in topics: keep them non-empty and free of "/",
    # which would make "to/<name>" ambiguous.
    if not isinstance(value, str) or not value or "/" in value:
        raise WireError(f"{name}: expected a non-empty name without '/', got {value!r}")
    return value


def _check_str(value: Any, name: str) -> str:
    if not isinstance(value, str):
        raise WireError(f"{name}: expected str, got {type(value).__name__}")
    return value


def _check_float(value: Any, name: str) -> float:
    # bool is an int subclass; a True in a coordinate is a bug, not a 1.0.
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise WireError(f"{name}: expected a number, got {type(value).__name__}")
    try:
        return float(value)
    except OverflowError as exc:  # ints beyond float range
        raise WireError(f"{name}: number out of range") from exc


def _check_bool(value: Any, name: str) -> bool:
    if not isinstance(value, bool):
        raise WireError(f"{name}: expected bool, got {type(value).__name__}")
    return value


def _check_iteration(value: Any, name: str) -> tuple[int, ...]:
    # Lists are accepted because msgpack decodes arrays as lists; the message
    # always holds a tuple so it stays hashable and compares equal after a trip.
    if not isinstance(value, tuple | list):
        raise WireError(f"{name}: expected a sequence of int, got {type(value).__name__}")
    for item in value:
        if isinstance(item, bool) or not isinstance(item, int):
            raise WireError(f"{name}: expected int items, got {item!r}")
    return tuple(value)


_MAX_SEQ: Final = (1 << 63) - 1


def _check_seq(value: Any, name: str) -> int:
    # Sequence numbers are compared and stored as ints; bools and floats are bugs.
    if type(value) is not int or not 0 <= value <= _MAX_SEQ:
        raise WireError(f"{name}: expected an int in [0, 2**63), got {value!r}")
    return value


def _check_seq_map(value: Any, name: str) -> dict[str, int]:
    if not isinstance(value, dict) or len(value) > _MAX_CONTAINER_LEN:
        raise WireError(f"{name}: expected a map of participant -> int")
    for key, item in value.items():
        _check_name(key, name)
        _check_seq(item, name)
    return value


#: Exact types of plain scalars: checked by one set lookup (a progress batch or a
#: report holds thousands of them); their subclasses take the isinstance tests below.
_SCALARS: Final = frozenset({type(None), bool, int, float, str, bytes})


def _check_plain(value: Any, name: str, depth: int) -> None:
    if depth > MAX_DEPTH:
        raise WireError(f"{name}: nested deeper than {MAX_DEPTH}")
    if type(value) in _SCALARS or isinstance(value, bool | int | float | str | bytes):
        return
    # A scalar item needs no call of its own (it is plain), unless at the depth limit.
    if isinstance(value, list | tuple):
        for item in value:
            if type(item) not in _SCALARS or depth >= MAX_DEPTH:
                _check_plain(item, name, depth + 1)
        return
    if isinstance(value, dict):
        for key, item in value.items():
            if type(key) is not str and not isinstance(key, str):
                raise WireError(f"{name}: map keys must be str, got {key!r}")
            if type(item) not in _SCALARS or depth >= MAX_DEPTH:
                _check_plain(item, name, depth + 1)
        return
    raise WireError(f"{name}: {type(value).__name__} is not plain data")


def _check_part_data(value: Any, name: str) -> bytes:
    if not isinstance(value, bytes) or len(value) > REPORT_PART_BYTES:
        raise WireError(f"{name}: expected at most {REPORT_PART_BYTES} bytes (bin)")
    return value


def _check_parts(value: Any, name: str) -> int:
    if type(value) is not int or not 1 <= value <= MAX_REPORT_PARTS:
        raise WireError(f"{name}: expected an int in [1, {MAX_REPORT_PARTS}], got {value!r}")
    return value


def _check_map(value: Any, name: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise WireError(f"{name}: expected a map, got {type(value).__name__}")
    _check_plain(value, name, 0)
    return value


def _check_choice(choices: frozenset[str]) -> Any:
    def check(value: Any, name: str) -> str:
        # isinstance first: membership of an unhashable value would raise TypeError.
        if not isinstance(value, str) or value not in choices:
            raise WireError(f"{name}: expected one of {sorted(choices)}, got {value!r}")
        return str(value)

    return check


def _m(key: str, check: Any) -> dict[str, Any]:
    """Field metadata: the field's wire key and its validator."""
    return {"key": key, "check": check}
