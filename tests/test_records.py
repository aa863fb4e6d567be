"""``@frozen`` behaves as ``@dataclass(frozen=True)``, ``@record`` as ``@dataclass``.

Each class shape is defined both ways; the pairs differ only in the decorator, and every
observable result (``__init__``'s signature, values and errors, repr, ==, hash,
immutability, replace, pickling, match) must be the same.
"""

from __future__ import annotations

import dataclasses
import inspect
import pickle
from dataclasses import dataclass, field
from typing import Any

import pytest

import eamos
from eamos import records as records_module
from eamos.records import frozen, record

#: Each kind: the ``dataclass`` decorator, and this package's that behaves as it.
KINDS: dict[str, tuple[Any, Any]] = {
    "frozen": (dataclass(frozen=True), frozen),
    "record": (dataclass, record),
}


def _pair(decorate_body: Any, kind: str = "frozen") -> tuple[type, type]:
    """The same class body decorated by ``dataclass`` and by ours, of ``kind``."""
    reference, ours = KINDS[kind]
    return decorate_body(reference), decorate_body(ours)


def _hash_or_error(value: Any) -> Any:
    """``hash(value)``, or the error's type and message (a record is not hashable)."""
    try:
        return hash(value)
    except TypeError as error:
        return (TypeError, str(error))


def plain(deco: Any) -> type:
    @deco
    class Point:
        """A point."""

        x: int
        y: float = 0.0
        tags: tuple[str, ...] = ()

    return Point


def options(deco: Any) -> type:
    @deco
    class Sample:
        """Fields with repr, compare and hash options."""

        name: str
        secret: str = field(default="", repr=False)
        stamp: float = field(default=0.0, compare=False)
        weight: int = field(default=1, hash=False)
        extra: dict[str, int] = field(default_factory=dict, compare=False, hash=False)

    return Sample


def empty(deco: Any) -> type:
    @deco
    class Nothing:
        """No fields."""

    return Nothing


def one(deco: Any) -> type:
    @deco
    class One:
        """One field (a getter of one name returns no tuple)."""

        value: Any

    return One


def derived(deco: Any) -> type:
    @deco
    class Base:
        """A base."""

        a: int

    @deco
    class Child(Base):
        """Adds a field, kw_only."""

        b: int = field(default=2, kw_only=True)

    return Child


def own_methods(deco: Any) -> type:
    @deco
    class Own:
        """Defines __eq__ (so its body's __hash__ is None) and __repr__ itself."""

        a: int

        def __eq__(self, other: object) -> bool:
            return isinstance(other, Own) and abs(self.a - other.a) < 2

        def __repr__(self) -> str:
            return "own"

    return Own


def own_hash(deco: Any) -> type:
    @deco
    class Hashed:
        """Defines __hash__ itself."""

        a: int

        def __hash__(self) -> int:
            return 7

    return Hashed


def factories(deco: Any) -> type:
    @deco
    class Made:
        """Fields with factories, one not in __init__, and a keyword-only one in between."""

        a: int
        items: list[int] = field(default_factory=list, hash=False)
        count: int = field(default=0, kw_only=True)
        seen: set[str] = field(default_factory=set, init=False, hash=False)
        b: str = "b"

    return Made


def checked(deco: Any) -> type:
    @deco
    class Checked:
        """Checks itself in __post_init__ (and a field may be called self)."""

        self: int
        low: int = 0

        def __post_init__(self) -> None:
            if self.self < self.low:
                raise ValueError(f"{self.self} < {self.low}")

    return Checked


SHAPES = [plain, options, empty, one, derived, own_methods, own_hash, factories, checked]
#: Arguments to build two instances per shape (equal-or-not varies by shape).
ARGS: dict[Any, list[tuple[tuple[Any, ...], dict[str, Any]]]] = {
    plain: [((1,), {}), ((1, 0.0, ()), {}), ((1, 2.5, ("a",)), {}), ((2,), {})],
    options: [
        (("n",), {}),
        (("n",), {"secret": "s", "stamp": 3.0, "extra": {"k": 1}}),
        (("n",), {"weight": 5}),
        (("m",), {}),
    ],
    empty: [((), {}), ((), {})],
    one: [((1,), {}), ((1.0,), {}), (("1",), {}), (((1, 2),), {})],
    derived: [((1,), {}), ((1,), {"b": 2}), ((1,), {"b": 3})],
    own_methods: [((1,), {}), ((2,), {}), ((5,), {})],
    own_hash: [((1,), {}), ((2,), {})],
    factories: [((1,), {}), ((1, [2]), {"count": 3}), ((1,), {"b": "c", "items": [2]})],
    checked: [((1,), {}), ((2,), {"low": 1}), ((), {"self": 3, "low": 3})],
}
#: Calls each shape's ``__init__`` refuses (same exception, same message, both ways).
BAD_CALLS: dict[Any, list[tuple[tuple[Any, ...], dict[str, Any]]]] = {
    plain: [((), {}), ((1, 2, 3, 4), {}), ((1,), {"z": 1}), ((1,), {"x": 2})],
    options: [((), {"secret": "s"})],
    empty: [((1,), {})],
    one: [((), {}), ((1,), {"value": 1})],
    derived: [((1, 2), {})],
    own_methods: [((), {})],
    own_hash: [((), {})],
    factories: [((), {}), ((1, [], "b", 4), {}), ((1,), {"seen": set()})],
    checked: [((0,), {"low": 1}), ((), {})],
}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.__name__)
def test_value_methods_match_dataclass(shape: Any, kind: str) -> None:
    reference, ours = _pair(shape, kind)
    assert dataclasses.is_dataclass(ours)
    assert [f.name for f in dataclasses.fields(ours)] == [
        f.name for f in dataclasses.fields(reference)
    ]
    assert str(inspect.signature(ours)) == str(inspect.signature(reference))
    our_init, reference_init = vars(ours)["__init__"], vars(reference)["__init__"]
    assert our_init.__annotations__ == reference_init.__annotations__
    assert our_init.__qualname__ == reference_init.__qualname__
    assert ours.__doc__ == reference.__doc__
    assert ours.__match_args__ == reference.__match_args__  # type: ignore[attr-defined]
    made = [(reference(*a, **k), ours(*a, **k)) for a, k in ARGS[shape]]
    for ref_x, our_x in made:
        assert vars(our_x) == vars(ref_x)
        assert repr(our_x) == repr(ref_x)
        for ref_y, our_y in made:
            assert (our_x == our_y) is (ref_x == ref_y)
            assert (our_x != our_y) is (ref_x != ref_y)
        # Both hash the tuple of the same fields: the very same number (or neither can).
        assert _hash_or_error(our_x) == _hash_or_error(ref_x)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.__name__)
def test_init_refuses_what_dataclass_refuses_with_its_message(shape: Any, kind: str) -> None:
    for args, kwargs in BAD_CALLS[shape]:
        errors = []
        for cls in _pair(shape, kind):
            with pytest.raises((TypeError, ValueError)) as caught:
                cls(*args, **kwargs)
            errors.append((type(caught.value), str(caught.value)))
        assert errors[0] == errors[1], (args, kwargs)


@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.__name__)
def test_every_field_is_immutable_as_in_dataclass(shape: Any) -> None:
    for cls in _pair(shape):
        args, kwargs = ARGS[shape][0]
        value = cls(*args, **kwargs)
        for name in [*(f.name for f in dataclasses.fields(value)), "other"]:
            with pytest.raises(dataclasses.FrozenInstanceError, match=f"assign to field '{name}'"):
                setattr(value, name, 1)
            with pytest.raises(dataclasses.FrozenInstanceError, match=f"delete field '{name}'"):
                delattr(value, name)


@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.__name__)
def test_a_record_changes_as_a_dataclass_does(shape: Any) -> None:
    changed = []
    for cls in _pair(shape, "record"):
        args, kwargs = ARGS[shape][0]
        value = cls(*args, **kwargs)
        for f in dataclasses.fields(value):
            setattr(value, f.name, "new")
        value.other = 1
        changed.append((vars(value), repr(value)))
        for f in dataclasses.fields(value):
            delattr(value, f.name)
    assert changed[0] == changed[1]


@pytest.mark.parametrize("kind", KINDS)
def test_factories_give_each_instance_its_own_value(kind: str) -> None:
    _, made = _pair(factories, kind)
    first, second = made(1), made(1)
    assert first.items == [] and first.items is not second.items
    assert first.seen == set() and first.seen is not second.seen


def test_a_plain_subclass_may_set_what_is_not_a_field() -> None:
    for cls in _pair(plain):

        class Marked(cls):  # type: ignore[valid-type, misc]
            def __init__(self, x: int) -> None:
                super().__init__(x)
                self.mark = "set"

        assert Marked(1).mark == "set"
        with pytest.raises(dataclasses.FrozenInstanceError):
            Marked(1).x = 2


def test_class_definitions_dataclass_refuses_are_refused() -> None:
    for deco in (dataclass(frozen=True), frozen, dataclass, record):
        with pytest.raises(TypeError, match="non-default argument 'b' follows default argument"):

            @deco
            class Order:
                a: int = 1
                b: int  # type: ignore[misc]

        with pytest.raises(ValueError, match="mutable default"):

            @deco
            class Mutable:
                a: list[int] = []

    for deco in (dataclass(frozen=True), frozen):
        with pytest.raises(TypeError, match="Cannot overwrite attribute __setattr__"):

            @deco
            class Own:
                a: int

                def __setattr__(self, name: str, value: Any) -> None:
                    pass

    for deco in (frozen, record):
        with pytest.raises(TypeError, match="InitVar"):

            @deco
            class Initialised:
                a: dataclasses.InitVar[int]


def test_frozen_and_mutable_do_not_mix_as_in_dataclass() -> None:
    for frozen_deco, mutable_deco in ((dataclass(frozen=True), dataclass), (frozen, record)):

        @frozen_deco
        class Fixed:
            a: int

        @mutable_deco
        class Loose:
            a: int

        with pytest.raises(TypeError, match="cannot inherit non-frozen dataclass from a frozen"):
            mutable_deco(type("Child", (Fixed,), {"__annotations__": {"b": "int"}}))
        with pytest.raises(TypeError, match="cannot inherit frozen dataclass from a non-frozen"):
            frozen_deco(type("Child", (Loose,), {"__annotations__": {"b": "int"}}))
    with pytest.raises(TypeError, match="cannot extend @dataclass"):
        frozen(type("Child", (_pair(plain)[0],), {"__annotations__": {"b": "int"}}))


def test_a_record_honours_its_own_setattr_in_init() -> None:
    seen = []

    @record
    class Watched:
        a: int
        b: str = "b"

        def __setattr__(self, name: str, value: Any) -> None:
            seen.append(name)  # as ``self.a = a`` in dataclass' __init__ would call it
            object.__setattr__(self, name, value)

    assert vars(Watched(1)) == {"a": 1, "b": "b"} and seen == ["a", "b"]


def test_init_is_compiled_once_per_form_of_field_list() -> None:
    @frozen
    class First:
        """Two fields, the second with a default."""

        a: int
        b: str = ""

    @frozen
    class Second:
        """Other names, the same form."""

        x: float
        y: bytes = b""

    @record
    class Third:
        """A record of the same form."""

        m: int
        n: int = 0

    # One compiled body, two names each: the code differs only in the names it holds.
    assert First.__init__.__code__.co_code == Second.__init__.__code__.co_code
    assert First.__init__.__code__.co_varnames == ("self", "a", "b")
    assert Second.__init__.__code__.co_varnames == ("self", "x", "y")
    assert vars(Second(1.0)) == {"x": 1.0, "y": b""}
    # A record sets its fields as ``self.name = value``: the names are the code's own.
    assert Third.__init__.__code__.co_names == ("m", "n")
    assert vars(Third(1)) == {"m": 1, "n": 0}


def test_hash_reads_the_fields_dataclass_hashes() -> None:
    _, sample = _pair(options)
    a, b = sample("n"), sample("n", stamp=9.0, weight=4, extra={"x": 1})
    assert hash(a) == hash(b)  # stamp, weight and extra are not hashed
    assert hash(sample("n")) != hash(sample("m"))


def test_other_classes_and_tuples_are_not_equal() -> None:
    _, point = _pair(plain)
    _, one_cls = _pair(one)
    p = point(1)
    assert p != (1, 0.0, ())
    assert p.__eq__((1, 0.0, ())) is NotImplemented
    assert one_cls(1) != point(1)

    @frozen
    class Sub(point):  # type: ignore[valid-type, misc]
        """A subclass with no field of its own."""

    assert Sub(1) != p and p != Sub(1)


@frozen
class Pickled:
    """At module level, so that pickle finds it."""

    x: int
    y: float


def test_frozen_replace_pickle_and_match() -> None:
    _, point = _pair(plain)
    p = point(1, 2.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.x = 3
    with pytest.raises(dataclasses.FrozenInstanceError):
        del p.y
    assert dataclasses.replace(p, x=3) == point(3, 2.0)
    kept = Pickled(1, 2.0)
    assert pickle.loads(pickle.dumps(kept)) == kept
    match p:
        case point(x, y):  # type: ignore[misc]
            assert (x, y) == (1, 2.0)
        case _:
            pytest.fail("no match")


@pytest.mark.parametrize("kind", KINDS)
def test_repr_of_an_instance_inside_itself_is_dots(kind: str) -> None:
    shown = []
    for holder_cls in _pair(one, kind):
        box: list[Any] = []
        holder = holder_cls(box)
        box.append(holder)
        shown.append(repr(holder))
    assert shown[0] == shown[1] and shown[1].endswith("One(value=[...])")


def test_every_record_class_of_eamos_keeps_dataclass_behaviour() -> None:
    """Each ``@frozen`` and ``@record`` class in the package is a dataclass, frozen or not."""
    import importlib
    import pkgutil

    found = {True: 0, False: 0}
    for info in pkgutil.walk_packages(eamos.__path__, "eamos."):
        if ".lsp" in info.name or ".monitor" in info.name or info.name.endswith("__main__"):
            continue  # optional server libraries; their classes are checked by their tests
        module = importlib.import_module(info.name)
        for value in vars(module).values():
            if isinstance(value, type) and "__record_values__" in value.__dict__:
                frozen_here = value.__setattr__ is records_module._setattr
                found[frozen_here] += 1
                assert dataclasses.is_dataclass(value), value
                assert (value.__hash__ is None) is not frozen_here, value
    assert found[True] > 150 and found[False] > 20
