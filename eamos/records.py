"""``@frozen`` and ``@record``: dataclasses that compile nothing per class, for start-up's sake.

``@frozen`` behaves as ``@dataclass(frozen=True)`` and ``@record`` as ``@dataclass``:
the same ``__init__`` (signature, defaults, ``default_factory``, ``kw_only``,
``__post_init__``), fields, ``dataclasses.replace`` / ``fields`` / ``asdict``, pickling,
``__match_args__``, ``repr`` and ``==``; a ``@frozen`` value is immutable
(:class:`dataclasses.FrozenInstanceError`) and hashable, a ``@record`` is neither
(``__hash__`` is None), as with ``dataclass``.  A type checker treats them as
``dataclass`` (:func:`typing.dataclass_transform`).  ``tests/test_records.py`` compares
them with ``dataclass``, class shape by class shape.

Why they exist: on Python 3.11, ``dataclass`` writes the source of three methods per
class (six when frozen) and compiles each with ``exec``: 0.2-0.4 ms a class, and a
drone's ``eamos-node`` defines about 130 such classes before it is ready
(docs/performance.md).  Here nothing is compiled per class:

* ``__repr__``, ``__eq__``, ``__hash__``, ``__setattr__`` and ``__delattr__`` are one
  shared function each, reading what the class names once at decoration
  (``__record_values__``: C-level getters of the compared and hashed fields, the names
  ``repr`` shows);
* ``__init__`` is compiled once per *form* of field list (how many fields, which take
  a ``default_factory``, which are keyword-only, whether ``__post_init__`` is called,
  frozen or not), with placeholder names; each class gets a copy of that code object
  with its own field names (:meth:`types.CodeType.replace`) and its own defaults, so its
  signature, its errors (``missing 1 required positional argument: 'x'``) and its speed
  are those of the ``__init__`` ``dataclass`` would have written.

``dataclass`` itself still collects the fields (``init=False, repr=False, eq=False``,
never ``frozen``: ``__dataclass_params__`` describes what ``dataclass`` generated, and
a ``@frozen`` class's immutability is this module's).  As with ``dataclass``, a
``@frozen`` class cannot inherit from a ``@record`` one nor the reverse; nor can either
mix with a ``@dataclass`` of the other kind.  A method the class body defines itself
(``__repr__``, ``__eq__``, ``__hash__``) is kept, as ``dataclass`` keeps it; a
``@frozen`` body that defines ``__setattr__`` or ``__delattr__`` is refused, as
``dataclass(frozen=True)`` refuses it.

Only the plain form exists: a class that needs ``order``, ``slots``, ``eq=False``,
``InitVar`` or other options stays a ``@dataclass(...)``.
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Callable
from functools import cache
from operator import attrgetter
from reprlib import recursive_repr
from types import CodeType, FunctionType
from typing import Any, TypeVar, dataclass_transform

__all__ = ["frozen", "record"]

C = TypeVar("C", bound=type)

#: How a field reaches ``__init__``'s body (see :func:`_init_code`).
_ARGUMENT = "argument"  # set from its parameter
_FACTORY_ARGUMENT = "factory argument"  # its parameter, or its factory's value if omitted
_FACTORY_ONLY = "factory only"  # ``init=False`` with a factory: always the factory's value
#: ``init=False`` without a factory: not set (the class attribute is the default).
_NOT_SET = "not set"


class _FactoryDefault:
    """The default of a parameter whose field has a ``default_factory`` (shown ``<factory>``)."""

    def __repr__(self) -> str:
        return "<factory>"


_FACTORY = _FactoryDefault()


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
        compared = self.__record_values__[0]
        return compared(self) == compared(other)
    return NotImplemented


def _hash(self: Any) -> int:
    return hash(self.__record_values__[1](self))


@recursive_repr()  # as ``dataclasses``' own: an instance met again inside itself is "..."
def _repr(self: Any) -> str:
    shown = self.__record_values__[2]
    fields = ", ".join(f"{name}={getattr(self, name)!r}" for name in shown)
    return f"{self.__class__.__qualname__}({fields})"


def _is_frozen_here(self: Any, name: str) -> bool:
    """``dataclasses``' rule: an instance of a frozen class itself, or one of its fields."""
    cls = type(self)
    return "__record_values__" in cls.__dict__ or name in cls.__dataclass_fields__


def _setattr(self: Any, name: str, value: Any) -> None:
    if _is_frozen_here(self, name):
        raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")
    object.__setattr__(self, name, value)


def _delattr(self: Any, name: str) -> None:
    if _is_frozen_here(self, name):
        raise dataclasses.FrozenInstanceError(f"cannot delete field {name!r}")
    object.__delattr__(self, name)


def _placeholder(index: int) -> str:
    """The name field ``index`` has in a compiled form (no field is called so)."""
    return f"_record_field_{index}_"


def _is_frozen(cls: type) -> bool:
    """Whether ``cls`` (or the dataclass it derives from) is frozen, by this module or not."""
    if getattr(cls, "__setattr__", None) is _setattr:
        return True
    params = getattr(cls, "__dataclass_params__", None)
    return bool(params is not None and params.frozen)


@cache  # one compilation per form; a class's __init__ is a renamed copy of it
def _init_code(
    self_name: str, forms: tuple[tuple[str, bool], ...], post_init: bool, frozen: bool
) -> CodeType:
    """The code of ``__init__`` for fields of ``forms`` ((how set, keyword-only) each).

    Field ``i`` is called :func:`_placeholder` ``(i)``: its parameter, and the attribute
    it sets, as ``dataclass`` sets it: ``_set(self, name, value)`` (``_set`` is
    ``object.__setattr__``) when ``frozen``, ``self.name = value`` otherwise.
    ``_FACTORY`` is the factory default, ``_factory_i`` field ``i``'s factory (both
    from the globals).
    """

    def assign(name: str, value: str) -> str:
        if frozen:
            return f"_set({self_name}, {name!r}, {value})"
        return f"{self_name}.{name} = {value}"

    positional: list[str] = []
    keyword: list[str] = []
    body: list[str] = []
    for index, (how, kw_only) in enumerate(forms):
        name = _placeholder(index)
        if how in (_ARGUMENT, _FACTORY_ARGUMENT):
            (keyword if kw_only else positional).append(name)
        if how == _ARGUMENT:
            body.append(assign(name, name))
        elif how == _FACTORY_ARGUMENT:
            body.append(assign(name, f"_factory_{index}() if {name} is _FACTORY else {name}"))
        elif how == _FACTORY_ONLY:
            body.append(assign(name, f"_factory_{index}()"))
    if post_init:
        body.append(f"{self_name}.__post_init__()")
    params = [self_name, *positional, *(["*", *keyword] if keyword else [])]
    lines = "\n    ".join(body or ["pass"])
    source = f"def __init__({', '.join(params)}):\n    {lines}\n"
    namespace: dict[str, Any] = {}
    exec(compile(source, "<record __init__>", "exec"), namespace)  # our own text
    code: CodeType = namespace["__init__"].__code__
    return code


def _how(f: dataclasses.Field[Any]) -> str:
    """How field ``f`` reaches ``__init__``'s body (the forms of :func:`_init_code`)."""
    has_factory = f.default_factory is not dataclasses.MISSING
    if f.init:
        return _FACTORY_ARGUMENT if has_factory else _ARGUMENT
    return _FACTORY_ONLY if has_factory else _NOT_SET


def _init_default(f: dataclasses.Field[Any]) -> Any:
    """The default of ``f``'s ``__init__`` parameter: ``_FACTORY``, its value, or MISSING."""
    if f.default_factory is not dataclasses.MISSING:
        return _FACTORY
    return f.default


def _check_defaults_order(fields: tuple[dataclasses.Field[Any], ...]) -> None:
    """``dataclasses``' error for a positional field without default after one with."""
    seen_default = False
    for f in fields:
        if not f.init or f.kw_only is True:
            continue
        if _init_default(f) is not dataclasses.MISSING:
            seen_default = True
        elif seen_default:
            raise TypeError(f"non-default argument {f.name!r} follows default argument")


def _make_init(
    cls: type, fields: tuple[dataclasses.Field[Any], ...], frozen: bool
) -> Callable[..., None]:
    """``cls``'s ``__init__``: the compiled form of its fields, renamed and given defaults."""
    _check_defaults_order(fields)
    names = [f.name for f in fields]
    self_name = "__dataclass_self__" if "self" in names else "self"
    forms = tuple((_how(f), f.kw_only is True) for f in fields)
    code = _init_code(self_name, forms, hasattr(cls, "__post_init__"), frozen)
    renamed = {_placeholder(i): name for i, name in enumerate(names)}
    code = code.replace(
        co_varnames=tuple(renamed.get(n, n) for n in code.co_varnames),
        co_names=tuple(renamed.get(n, n) for n in code.co_names),  # ``self.name = ...``
        co_consts=tuple(renamed.get(c, c) if isinstance(c, str) else c for c in code.co_consts),
        co_name="__init__",
        co_qualname=f"{cls.__qualname__}.__init__",
    )
    scope: dict[str, Any] = {"_set": object.__setattr__, "_FACTORY": _FACTORY}
    defaults, kw_defaults = [], {}
    for index, f in enumerate(fields):
        if f.default_factory is not dataclasses.MISSING:
            scope[f"_factory_{index}"] = f.default_factory
        default = _init_default(f)
        if not f.init or default is dataclasses.MISSING:
            continue
        if f.kw_only is True:
            kw_defaults[f.name] = default
        else:
            defaults.append(default)
    init = FunctionType(code, scope, "__init__", tuple(defaults) or None)
    init.__kwdefaults__ = kw_defaults or None
    init.__qualname__ = f"{cls.__qualname__}.__init__"
    init.__module__ = cls.__module__
    init.__annotations__ = {f.name: f.type for f in fields if f.init} | {"return": None}
    return init


def _explicit_hash(cls: type) -> bool:
    """Whether the class body defines ``__hash__`` itself (``dataclasses``' own rule)."""
    body = cls.__dict__
    if "__hash__" not in body:
        return False
    # ``__eq__`` in a body sets ``__hash__ = None`` there: that is not an explicit hash.
    return not (body["__hash__"] is None and "__eq__" in body)


def _refuse_before(cls: type, frozen: bool) -> None:
    """``dataclass``' refusals about the class body and its bases, before it runs."""
    for base in cls.__mro__[1:]:
        if "__dataclass_fields__" not in base.__dict__:
            continue
        if _is_frozen(base) and not frozen:
            raise TypeError("cannot inherit non-frozen dataclass from a frozen one")
        if frozen and not _is_frozen(base):
            raise TypeError("cannot inherit frozen dataclass from a non-frozen one")
        if frozen and base.__dataclass_params__.frozen:  # type: ignore[attr-defined]
            raise TypeError(f"@frozen cannot extend @dataclass(frozen=True) {base.__name__}")
    if frozen:
        for name in ("__setattr__", "__delattr__"):
            if name in cls.__dict__:
                raise TypeError(f"Cannot overwrite attribute {name} in class {cls.__name__}")


def _decorate(cls: Any, frozen: bool) -> Any:
    """``cls`` made a dataclass with this module's methods (see the module's docstring)."""
    _refuse_before(cls, frozen)
    explicit_hash = _explicit_hash(cls)
    documented = bool(cls.__dict__.get("__doc__"))
    if not documented:
        # Else dataclass writes one from inspect.signature of object.__init__ (init=False
        # here), which parses its text signature with tokenize: ~2 ms the first time.
        cls.__doc__ = "(written below)"
    made: Any = dataclasses.dataclass(init=False, repr=False, eq=False)(cls)
    for f in made.__dataclass_fields__.values():  # pseudo-fields are known only now
        if "InitVar" in str(f.type):
            raise TypeError(f"@frozen and @record take no InitVar ({cls.__name__}.{f.name})")
    fields = dataclasses.fields(made)
    body = made.__dict__
    if "__init__" not in body:
        made.__init__ = _make_init(made, fields, frozen)
    compared = tuple(f.name for f in fields if f.compare)
    hashed = tuple(f.name for f in fields if (f.compare if f.hash is None else f.hash))
    shown = tuple(f.name for f in fields if f.repr)
    # What the shared methods read: getters of the compared and the hashed fields, the
    # names shown by repr.
    made.__record_values__ = (_tuple_of(compared), _tuple_of(hashed), shown)
    if "__repr__" not in body:
        made.__repr__ = _repr
    if "__eq__" not in body:
        made.__eq__ = _eq
    if not explicit_hash:
        # dataclass: a frozen class hashes its fields; a mutable one is not hashable.
        made.__hash__ = _hash if frozen else None
    if frozen:
        made.__setattr__ = _setattr
        made.__delattr__ = _delattr
    if not documented:  # as dataclass writes it, from the __init__ made above
        made.__doc__ = made.__name__ + str(inspect.signature(made)).replace(" -> None", "")
    return made


@dataclass_transform(frozen_default=True, field_specifiers=(dataclasses.field, dataclasses.Field))
def frozen(cls: C) -> C:
    """``cls`` as ``@dataclass(frozen=True)`` makes it, with nothing compiled for it."""
    made: C = _decorate(cls, frozen=True)
    return made


@dataclass_transform(field_specifiers=(dataclasses.field, dataclasses.Field))
def record(cls: C) -> C:
    """``cls`` as ``@dataclass`` makes it (mutable, not hashable), with nothing compiled for it."""
    made: C = _decorate(cls, frozen=False)
    return made
