"""``@frozen`` behaves as ``@dataclass(frozen=True)``: each class shape defined both ways.

The pairs differ only in the decorator; every observable result of the value methods
(repr, ==, hash, immutability, replace, pickling, match) must be the same.
"""

from __future__ import annotations

import dataclasses
import pickle
from dataclasses import dataclass, field
from typing import Any

import pytest

import eamos
from eamos.frozen import frozen


def _pair(decorate_body: Any) -> tuple[type, type]:
    """The same class body decorated by ``dataclass(frozen=True)`` and by ``frozen``."""
    return decorate_body(dataclass(frozen=True)), decorate_body(frozen)


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


SHAPES = [plain, options, empty, one, derived, own_methods, own_hash]
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
}


@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: s.__name__)
def test_value_methods_match_dataclass(shape: Any) -> None:
    reference, ours = _pair(shape)
    assert dataclasses.is_dataclass(ours) and ours.__dataclass_params__.frozen  # type: ignore[attr-defined]
    assert [f.name for f in dataclasses.fields(ours)] == [
        f.name for f in dataclasses.fields(reference)
    ]
    made = [(reference(*a, **k), ours(*a, **k)) for a, k in ARGS[shape]]
    for ref_x, our_x in made:
        assert repr(our_x) == repr(ref_x)
        for ref_y, our_y in made:
            assert (our_x == our_y) is (ref_x == ref_y)
            assert (our_x != our_y) is (ref_x != ref_y)
        # Both hash the tuple of the same fields: the very same number.
        assert hash(our_x) == hash(ref_x)


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


def test_repr_of_an_instance_inside_itself_is_dots() -> None:
    shown = []
    for holder_cls in _pair(one):
        box: list[Any] = []
        holder = holder_cls(box)
        box.append(holder)
        shown.append(repr(holder))
    assert shown[0] == shown[1] and shown[1].endswith("One(value=[...])")


def test_every_frozen_class_of_eamos_keeps_dataclass_behaviour() -> None:
    """Each ``@frozen`` class in the package is a frozen dataclass with the shared methods."""
    import importlib
    import pkgutil

    found = 0
    for info in pkgutil.walk_packages(eamos.__path__, "eamos."):
        if ".lsp" in info.name or ".monitor" in info.name or info.name.endswith("__main__"):
            continue  # optional server libraries; their classes are checked by their tests
        module = importlib.import_module(info.name)
        for value in vars(module).values():
            if isinstance(value, type) and "__frozen_values__" in value.__dict__:
                found += 1
                assert value.__dataclass_params__.frozen, value  # type: ignore[attr-defined]
    assert found > 150
