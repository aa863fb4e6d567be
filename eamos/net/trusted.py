"""Wire messages of values this process made itself, built without the field checks.

Every field of a :mod:`eamos.net.wire` message names a validator, run by the
constructor (a bad message fails at its sender) and by :func:`~eamos.net.wire.decode`
(the trust boundary: what a peer sends).  On the sender's hot path -- a trigger per
action -- the values come from the loaded program, the node logic and the
session, whose types already guarantee what the checks test; :func:`trusted`
builds such a message in a quarter of the constructor's time.
"""

from __future__ import annotations

from dataclasses import MISSING, fields
from typing import Any, Final, TypeVar

from eamos.net.wire import MESSAGE_TYPES, Message

__all__ = ["trusted"]

MessageT = TypeVar("MessageT", bound=Message)

# Per type: the fields' default values, the factories of the others (called per
# message: a fresh dict each), and every field's name.
_DEFAULTS: Final[dict[type, dict[str, Any]]] = {
    cls: {f.name: f.default for f in fields(cls) if f.default is not MISSING}
    for cls in MESSAGE_TYPES
}
_FACTORIES: Final[dict[type, tuple[tuple[str, Any], ...]]] = {
    cls: tuple((f.name, f.default_factory) for f in fields(cls) if f.default_factory is not MISSING)
    for cls in MESSAGE_TYPES
}
_FIELD_NAMES: Final[dict[type, frozenset[str]]] = {
    cls: frozenset(f.name for f in fields(cls)) for cls in MESSAGE_TYPES
}


def trusted(cls: type[MessageT], **values: Any) -> MessageT:
    """A ``cls`` message of ``values`` (this process's own), without the field checks.

    The caller vouches for the types (tuples for arrays, names without ``/``, a
    status among the allowed ones); what a peer sends is still checked field by
    field by :func:`~eamos.net.wire.decode`.  Fields left out take their defaults;
    an unknown field is a :class:`TypeError`.
    """
    names = _FIELD_NAMES[cls]
    if not values.keys() <= names:
        raise TypeError(f"{cls.__name__} has no field(s) {sorted(values.keys() - names)}")
    msg = cls.__new__(cls)
    made = msg.__dict__
    made.update(_DEFAULTS[cls])
    for name, factory in _FACTORIES[cls]:
        made[name] = factory()
    made.update(values)
    return msg
