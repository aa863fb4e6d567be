"""``@frozen``: a frozen dataclass whose value methods are shared, for start-up's sake.

``@frozen`` is ``@dataclass(frozen=True)``: the same ``__init__``, fields, immutability,
``dataclasses.replace`` / ``fields`` / ``asdict``, pickling and ``__match_args__``; a
type checker treats it as one (:func:`typing.dataclass_transform`).  It differs in how
three methods come about.  On Python 3.11, ``dataclass`` writes the source of six
methods per frozen class (``__init__``, ``__repr__``, ``__eq__``, ``__hash__``,
``__setattr__``, ``__delattr__``) and compiles each with ``exec``: about 0.3 ms a
class, and a drone's ``eamos-node`` defines over a hundred of them before it is ready.
Here ``__repr__``, ``__eq__`` and ``__hash__`` are one shared function each, reading
the fields the class names once at decoration (C-level getters), so each class
compiles three methods instead of six.

Their results are those of the generated methods (``tests/test_frozen.py`` compares
them): ``repr`` shows the fields with ``repr=True`` as ``Class(a=1, b='x')`` (``...``
for a value that contains itself); ``==`` holds between instances of the very same
class whose ``compare=True`` fields are equal (otherwise ``NotImplemented``);
``hash`` hashes the tuple of the fields ``dataclasses`` would hash.  A method the class
body defines itself is kept, as ``dataclass`` keeps it.

Only the plain form exists: a class that needs ``order``, ``slots`` or other options
stays a ``@dataclass(frozen=True, ...)``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from operator import attrgetter
from reprlib import recursive_repr
from typing import Any, TypeVar, dataclass_transform

__all__ = ["frozen"]

C = TypeVar("C", bound=type)


def _tuple_of(names: tuple[str, ...]) -> Callable[[Any], tuple[Any, ...]]:
    """A getter of ``names`` that always returns a tuple (``attrgetter`` of one name does not)."""
    if not names:
        return lambda obj: ()
    if len(names) == 1:
        one = attrgetter(names[0])
        return lambda obj: (one(obj),)
    return attrgetter(*names)  # type: ignore[return-value]  # a tuple for two names or more


def _eq(self: Any, other: Any) -> Any:
    if other.__class__ is self.__class__:
        compared = self.__frozen_values__[0]
        return compared(self) == compared(other)
    return NotImplemented


def _hash(self: Any) -> int:
    return hash(self.__frozen_values__[1](self))


@recursive_repr()  # as ``dataclasses``' own: an instance met again inside itself is "..."
def _repr(self: Any) -> str:
    shown = self.__frozen_values__[2]
    fields = ", ".join(f"{name}={getattr(self, name)!r}" for name in shown)
    return f"{self.__class__.__qualname__}({fields})"


def _explicit_hash(cls: type) -> bool:
    """Whether the class body defines ``__hash__`` itself (``dataclasses``' own rule)."""
    body = cls.__dict__
    if "__hash__" not in body:
        return False
    # ``__eq__`` in a body sets ``__hash__ = None`` there: that is not an explicit hash.
    return not (body["__hash__"] is None and "__eq__" in body)


@dataclass_transform(frozen_default=True, field_specifiers=(dataclasses.field, dataclasses.Field))
def frozen(cls: C) -> C:
    """``cls`` as a frozen dataclass with shared ``__repr__``, ``__eq__`` and ``__hash__``."""
    explicit_hash = _explicit_hash(cls)
    made: Any = dataclasses.dataclass(frozen=True, repr=False, eq=False)(cls)
    fields = dataclasses.fields(made)
    compared = tuple(f.name for f in fields if f.compare)
    hashed = tuple(f.name for f in fields if (f.compare if f.hash is None else f.hash))
    shown = tuple(f.name for f in fields if f.repr)
    # What the shared methods read: getters of the compared and the hashed fields, the
    # names shown by repr.
    made.__frozen_values__ = (_tuple_of(compared), _tuple_of(hashed), shown)
    body = made.__dict__
    if "__repr__" not in body:
        made.__repr__ = _repr  # type: ignore[assignment]
    if "__eq__" not in body:
        made.__eq__ = _eq  # type: ignore[assignment]
    if not explicit_hash:
        made.__hash__ = _hash  # type: ignore[assignment]
    return made
