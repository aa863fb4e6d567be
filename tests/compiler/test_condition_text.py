"""Conditions print as a person writes them: Go precedence, no redundant brackets.

Round trip: any condition tree, printed by ``to_text`` and compiled back in a
mission, is the same tree; and the text has no bracket that Go would not need.
"""

from __future__ import annotations

from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from eamos.compiler import compile_mission
from eamos.program.conditions import to_text

PROPS = st.sampled_from([["prop", "D1", "X"], ["prop", "D1", "Battery"], ["prop", "D2", "Z"]])
NUMS = st.integers(0, 50).map(lambda n: ["num", float(n)])


def arith(depth: int) -> Any:
    leaf = st.one_of(PROPS, NUMS)
    if depth == 0:
        return leaf
    sub = arith(depth - 1)
    return st.one_of(
        leaf,
        st.tuples(st.sampled_from(["+", "-", "*", "/"]), sub, sub).map(list),
        sub.map(lambda e: ["neg", e]),
    )


def boolean(depth: int) -> Any:
    compare = st.tuples(st.sampled_from(["<", "<=", ">", ">=", "==", "!="]), arith(1), arith(1))
    leaf = compare.map(list)
    if depth == 0:
        return leaf
    sub = boolean(depth - 1)
    return st.one_of(
        leaf,
        st.tuples(st.sampled_from(["&&", "||"]), sub, sub).map(list),
        sub.map(lambda e: ["not", e]),
    )


def compiled_condition(text: str) -> Any:
    source = (
        "var D1 Quadcopter\nvar D2 Quadcopter\n"
        f"func SEQ_Main() {{ If({text}, SEQ_A, SEQ_B) }}\n"
        "func SEQ_A() { D1.Arm() }\nfunc SEQ_B() { D2.Arm() }\n"
    )
    amt = compile_mission(source, "t.go").amt
    (cond,) = [a["cond"] for _, a in amt.nodes(data=True) if "cond" in a]
    return cond


def normal(cond: Any) -> Any:
    """Numbers as floats (the compiler keeps ints as written)."""
    if cond[0] == "num":
        return ["num", float(cond[1])]
    if cond[0] in ("bool", "prop"):
        return list(cond)
    return [cond[0], *(normal(c) for c in cond[1:])]


@settings(max_examples=150, deadline=None)
@given(boolean(2))
def test_printed_conditions_compile_back_to_the_same_tree(cond):
    text = to_text(cond)
    assert normal(compiled_condition(text)) == normal(cond), text


def test_brackets_only_where_go_needs_them():
    x, y = ["prop", "D1", "X"], ["prop", "D1", "Y"]
    five = ["num", 5]
    a = [">", x, five]
    b = ["<", y, five]
    c = ["==", ["prop", "D2", "Z"], ["num", 1]]
    assert to_text(["&&", ["&&", a, b], c]) == "D1.X() > 5 && D1.Y() < 5 && D2.Z() == 1"
    assert to_text(["&&", a, ["||", b, c]]) == "D1.X() > 5 && (D1.Y() < 5 || D2.Z() == 1)"
    assert to_text(["||", ["&&", a, b], c]) == "D1.X() > 5 && D1.Y() < 5 || D2.Z() == 1"
    assert to_text([">", ["-", x, ["-", y, five]], five]) == "D1.X() - (D1.Y() - 5) > 5"
    assert to_text([">", ["*", ["+", x, y], five], five]) == "(D1.X() + D1.Y()) * 5 > 5"
    assert to_text(["not", a]) == "!(D1.X() > 5)"
    assert to_text(["<", ["neg", x], ["num", -3]]) == "-D1.X() < -3"
