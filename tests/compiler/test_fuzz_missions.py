"""Fuzzing bad and odd missions (issue 17): only MissionError, located, bounded.

Hypothesis builds missions out of the classes that crashed or hung the
compiler: numbers too large for a float, deep nesting of operators and
blocks (around and far past the caps), blocks copied exponentially, odd line
ends and whitespace, non-Latin and over-long names.  Every one must compile
or raise a MissionError whose every diagnostic points inside the text, within
:data:`~.hostile.SECONDS_PER_MISSION`.  A second test checks that a known
mistake is located at the right *character* whatever comes before it.

Example counts are fixed (``EAMOS_HYPOTHESIS_EXAMPLES`` scales them) and the
runs derandomised, so CI sees the same missions every time.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from .hostile import caret_text, compile_checked

SCALE = float(os.environ.get("EAMOS_HYPOTHESIS_EXAMPLES", "1"))


def _settings(n: int) -> settings:
    return settings(
        max_examples=max(1, int(n * SCALE)),
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )


A4 = "\U0001d49c"  # a letter of four UTF-8 bytes
NAMES = ["D1", "Drone2", "\u0414\u0440\u043e\u043d", "\u7121\u4eba\u6a5f", A4 + A4, "D_3"]
ODD_NUMBERS = [
    "1",
    "-2.5",
    "1e999",
    "-1e999",
    "1e308",
    "9" * 400,
    "0x1p-2",
    "1_000",
    "0777",
    "10000",
    "10001",
    "86401",
    "-0",
    "1i",
    "NaN",
    "true",
    '"1"',
]
NEWLINES = ["\n", "\r\n", "\r"]
# Mostly Go whitespace; sometimes characters that are not (a located syntax error).
SPACES = ["\t", "\t", " ", "\f", "\v", "\t\f", "\u00a0", "\u2028", "\x85"]

# Nesting: mostly shallow, often just around the caps (100), sometimes far past them.
depth = st.one_of(
    st.integers(min_value=0, max_value=3),
    st.integers(min_value=0, max_value=8),
    st.integers(min_value=95, max_value=105),
    st.integers(min_value=106, max_value=700),
)
long_name = st.builds(
    lambda c, n: c * n, st.sampled_from(["D", "\u0414", A4]), st.integers(30, 300)
)
name = st.one_of(st.sampled_from(NAMES), st.sampled_from(NAMES), st.sampled_from(NAMES), long_name)


@st.composite
def number(draw: st.DrawFn) -> str:
    text = draw(st.sampled_from(ODD_NUMBERS))
    nest = draw(st.one_of(st.just(0), st.just(0), depth))
    wrap = draw(st.sampled_from(["(", "-(", "+("]))
    return wrap * nest + text + ")" * nest


@st.composite
def condition(draw: st.DrawFn) -> str:
    drone = draw(name)
    leaf = f"{drone}.{draw(st.sampled_from(['Z', 'X', 'Battery', 'Zz']))}() > {draw(number())}"
    shape = draw(st.sampled_from(["not", "and", "paren", "neg", "plain"]))
    n = draw(depth)
    if shape == "not":
        return "!" * n + f"({leaf})"
    if shape == "and":
        return " && ".join([leaf] * max(1, n))
    if shape == "paren":
        return "(" * n + leaf + ")" * n
    if shape == "neg":
        return f"{'-' * n}{drone}.Z() > 1"
    return leaf


@st.composite
def statement(draw: st.DrawFn) -> str:
    kind = draw(st.sampled_from(["action", "pause", "control", "repeat", "call"]))
    if kind == "action":
        action = draw(st.sampled_from(["FlyByX", "Takeoff", "FlyToXYZ", "Arm", "Flyy"]))
        args = ", ".join(draw(number()) for _ in range(3 if action == "FlyToXYZ" else 1))
        return f"{draw(name)}.{action}({'' if action == 'Arm' else args})"
    if kind == "pause":
        return f"PauseFor({draw(number())})"
    if kind == "control":
        structure = draw(st.sampled_from(["WaitUntil", "If", "DoWhile", "RepeatWhile"]))
        return f"{structure}({draw(condition())}, SEQ_Leaf)"
    if kind == "repeat":
        return f"RepeatFor({draw(number())}, SEQ_Leaf)"
    return "SEQ_C0()"


@st.composite
def odd_mission(draw: st.DrawFn) -> str:
    newline = draw(st.sampled_from(NEWLINES))
    space = draw(st.sampled_from(SPACES))
    lines = [f"// {draw(st.text(max_size=30))}".replace("\n", " ").replace("\r", " ")]
    lines.append(f"package {draw(name)}")
    lines += [f"var {draw(name)} Quadcopter" for _ in range(draw(st.integers(0, 2)))]
    statements = draw(st.lists(statement(), min_size=1, max_size=4))
    lines += ["func SEQ_Main() {", *(f"{space}{s}" for s in statements), "\tSEQ_C0()", "}"]
    # A chain of blocks: `length` deep, each calling the next `width` times.
    length = draw(st.one_of(st.integers(0, 20), st.integers(90, 110), st.integers(0, 600)))
    width = draw(st.integers(1, 3))
    for i in range(length):
        calls = [f"\tSEQ_C{i + 1}()"] * width
        lines += [f"func SEQ_C{i}() {{", *calls, "}"]
    lines += [f"func SEQ_C{length}() {{", "\tD1.Arm()", "}"]
    lines += ["func SEQ_Leaf() {", f"\t{draw(name)}.Land()", "}"]
    return newline.join(lines) + newline


@_settings(150)
@given(odd_mission())
def test_odd_missions_raise_only_located_mission_errors(text: str) -> None:
    compile_checked(text, "fuzz.go")


@_settings(150)
@given(
    st.lists(
        st.text(
            alphabet=st.characters(codec="utf-8", exclude_characters="\r\n\x00"),
            max_size=20,
        ),
        max_size=4,
    ),
    st.sampled_from(NEWLINES),
    st.lists(st.sampled_from(["\t", " ", "\f", "\v"]), min_size=1, max_size=3),
    st.sampled_from(NAMES),
)
def test_a_mistake_is_located_at_its_character(
    comments: list[str], newline: str, indent: list[str], drone: str
) -> None:
    """Whatever precedes it (any characters, any line ends), the caret is on ``Flyy``."""
    lines = [f"// {c}" for c in comments]
    lines += ["func SEQ_Main() {", f"{''.join(indent)}{drone}.Flyy(1)", "}"]
    text = newline.join(lines) + newline
    outcome = compile_checked(text, "loc.go")
    assert outcome.error is not None
    wanted = [d for d in outcome.error.diagnostics if d.message == "unknown action 'Flyy'"]
    assert len(wanted) == 1, outcome.error.diagnostics
    assert wanted[0].loc.line == len(comments) + 2
    assert caret_text(text, wanted[0]) == "Flyy"


@_settings(150)
@given(st.text(max_size=400))
def test_any_text_raises_only_located_mission_errors(text: str) -> None:
    compile_checked(text, "any.go")
