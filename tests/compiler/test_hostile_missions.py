"""A seeded corpus of the bad and odd missions of issue 17, one group per class.

Each found a crash (OverflowError, RecursionError), a hang (2^20 nodes,
quadratic printing) or a wrong location; each must now be a located
MissionError (or compile, at a limit), quickly and in little memory.
"""

from __future__ import annotations

import time
import tracemalloc

import pytest

from eamos.compiler import MissionError, compile_file, render_diagnostics
from eamos.compiler.dependency_graph import _MegIndex, _sync_arcs_error
from eamos.compiler.execution_graph import build_execution_graph
from eamos.compiler.limits import (
    MAX_BLOCK_DEPTH,
    MAX_DRONES,
    MAX_ERRORS,
    MAX_EXPRESSION_DEPTH,
    MAX_NAME_CHARS,
    MAX_REPEAT,
    MAX_SOURCE_BYTES,
    MAX_SYNC_ARCS,
    MAX_TREE_NODES,
    PROBE_BYTES,
    _BlockSizes,
    block_limit_errors,
)
from eamos.compiler.mission_tree import build_mission_tree
from eamos.compiler.parse import parse_mission
from eamos.program.conditions import evaluate, to_text, validate

from .compiler_helpers import mission_files
from .hostile import caret_text, compile_checked, text_at

# Written as escapes: the linter flags letters that look like Latin ones.
A4 = "\U0001d49c"  # MATHEMATICAL SCRIPT CAPITAL A: a letter of four UTF-8 bytes
DRON = "\u0414\u0440\u043e\u043d"  # "Drone" in Cyrillic: two bytes a letter
# Letters with combining marks: 201 characters that `\w` does not all match (issue 28).
COMBINING = "D" + "x\u0301" * 100


def _main(*statements: str, extra: str = "") -> str:
    body = "".join(f"\t{s}\n" for s in statements)
    return f"func SEQ_Main() {{\n{body}}}\n{extra}"


_BODY = "func SEQ_B() {\n\tD1.Arm()\n}\n"


def _chain(n: int) -> str:
    """``n`` blocks, each calling the next: they nest ``n`` deep."""
    calls = "".join(f"func SEQ_B{i}() {{\n\tSEQ_B{i + 1}()\n}}\n" for i in range(1, n))
    return calls + f"func SEQ_B{n}() {{\n\tD1.Arm()\n}}\n"


def _doubling(n: int) -> str:
    """The 739-byte bomb: ``n`` blocks each calling the next twice (2^n copies)."""
    calls = "".join(
        f"func SEQ_B{i}() {{\n\tSEQ_B{i + 1}()\n\tSEQ_B{i + 1}()\n}}\n" for i in range(n)
    )
    return calls + f"func SEQ_B{n}() {{\n\tD1.Arm()\n}}\n"


def _condition(expr: str) -> str:
    return _main(f"WaitUntil({expr}, SEQ_B)", extra=_BODY)


# -- numbers too large for a float --------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "token", "message"),
    [
        (_main("RepeatFor(1e999, SEQ_B)", extra=_BODY), "1e999", "too large a number"),
        (_main("D1.FlyByX(" + "9" * 400 + ")"), "9" * 30, "too large a number"),
        (_main("RepeatFor(" + "9" * 400 + ", SEQ_B)", extra=_BODY), "9" * 30, "too large"),
        (_main("D1.FlyByX(-1e999)"), "1e999", "too large a number"),
        (_main("D1.FlyToXYZ(1, 2, 1e400)"), "1e400", "too large a number"),
        (_condition("D1.Z() > 1e999"), "1e999", "too large a number"),
        (_main("PauseFor(1e308)"), "1e308", "duration_s must be within 0..86400 s"),
        (_main("D1.FlyByX(-1e6)"), "-1e6", "distance_m must be within -10000..10000 m"),
        (_main("D1.Takeoff(10000.5)"), "10000.5", "height_m must be within 0..10000 m"),
        (_main("D1.FlyToLLA(1, 2, 2e4)"), "2e4", "alt_m must be within"),
        (_main(f"RepeatFor({MAX_REPEAT + 1}, SEQ_B)", extra=_BODY), "1000001", "0 to 1000000"),
    ],
)
def test_out_of_range_numbers_are_located_errors(text: str, token: str, message: str) -> None:
    error = compile_checked(text).first_error()
    assert message in error.message
    assert text_at(text, error).startswith(token)


def test_numbers_at_the_bounds_compile() -> None:
    text = _main(
        "D1.Takeoff(10000)",
        "D1.FlyByX(-10000)",
        "D1.FlyToXYZ(10000, -10000, 10000)",
        "PauseFor(86400)",
        f"RepeatFor({MAX_REPEAT}, SEQ_B)",
        "WaitUntil(D1.Z() > 1e300, SEQ_B)",
        extra=_BODY,
    )
    assert compile_checked(text).compiled is not None


def test_signs_and_parentheses_keep_a_number_negative() -> None:
    compiled = compile_checked(_main("D1.FlyByX(-(2))", "D1.FlyByY(-(-(+(3))))")).compiled
    assert compiled is not None
    args = sorted(a["args"] for _, a in compiled.amt.nodes(data=True) if a["kind"] == "action")
    assert args == [(-2.0,), (3.0,)]


# -- nesting: no RecursionError, a cap far above a person's ----------------------------------


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (_chain(494), "blocks nest 494 deep from SEQ_B1, more than the limit of 100"),
        (_chain(5000), "blocks nest 5000 deep"),
        (_condition("!" * 495 + "D1.Armed()"), "nests operators and parentheses more than 100"),
        (_condition(" && ".join(["D1.Z() > 1"] * 496)), "more than 100 deep"),
        (_condition("(" * 985 + "D1.Z() > 1" + ")" * 985), "more than 100 deep"),
        (_main("D1.FlyByX(" + "(" * 985 + "1" + ")" * 985 + ")"), "this argument nests"),
        (_main("D1.FlyByX(" + "-(" * 600 + "1" + ")" * 600 + ")"), "this argument nests"),
        (_condition("-" * 3000 + "D1.Z() > 1"), "more than 100 deep"),
    ],
)
def test_deep_nesting_is_a_located_error(text: str, message: str) -> None:
    tracemalloc.start()
    try:
        outcome = compile_checked(text)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    error = outcome.first_error()
    assert message in error.message
    assert peak < 64 * 2**20


def test_the_block_nesting_error_points_at_the_call_that_crosses_the_limit() -> None:
    text = _chain(494)
    error = compile_checked(text).first_error()
    assert caret_text(text, error) == f"SEQ_B{MAX_BLOCK_DEPTH + 1}"
    assert error.loc.line == 3 * MAX_BLOCK_DEPTH - 1


def test_a_mission_at_every_nesting_cap_compiles_and_its_conditions_run() -> None:
    """100 nested blocks of If (the deepest Python stack per level), the innermost
    waiting on a condition of 100 nested operators; evaluated and printed at runtime."""
    deepest = " && ".join(["D1.Z() > 1"] * MAX_EXPRESSION_DEPTH)  # 99 && + 1 comparison
    blocks = [
        f"func SEQ_B{i}() {{\n\tIf(D1.Z() > {i}, SEQ_B{i + 1})\n}}\n"
        for i in range(1, MAX_BLOCK_DEPTH - 1)
    ]
    blocks.append(f"func SEQ_B{MAX_BLOCK_DEPTH - 1}() {{\n\tWaitUntil({deepest}, SEQ_Last)\n}}\n")
    blocks.append("func SEQ_Last() {\n\tD1.Arm()\n}\n")
    outcome = compile_checked("".join(blocks))
    assert outcome.compiled is not None, outcome.error
    conds = [a["cond"] for _, a in outcome.compiled.meg.nodes(data=True) if "cond" in a]
    cond = max(conds, key=lambda c: len(to_text(c)))
    validate(cond)
    assert evaluate(cond, lambda drone, prop: 2.0) is True
    nots = "!" * MAX_EXPRESSION_DEPTH + "D1.Armed()"
    assert compile_checked(_condition(nots)).compiled is not None
    assert compile_checked(_condition("!" + nots)).error is not None


def test_a_program_nesting_past_the_cap_is_refused_not_a_crash() -> None:
    from eamos.program.conditions import ConditionError

    cond: list[object] = ["bool", True]
    for _ in range(5000):
        cond = ["not", cond]
    with pytest.raises(ConditionError, match="nests more than 100"):
        validate(cond)
    with pytest.raises(ConditionError, match="finite"):
        validate(["num", float("inf")])
    with pytest.raises(ConditionError):
        validate([["num"], 1])


# -- expanded size: counted before expanding -------------------------------------------------


def test_a_block_bomb_is_refused_at_once_naming_the_block_and_its_size() -> None:
    text = _doubling(20)
    tracemalloc.start()
    try:
        outcome = compile_checked(text)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    error = outcome.first_error()
    assert error.message.startswith("block 'SEQ_B5' expands to 98 303 mission-tree nodes")
    assert "more than the limit of 50 000 (the whole mission: 3 145 727)" in error.message
    assert "it calls SEQ_B6 twice" in error.hint
    assert caret_text(text, error) == "SEQ_B5"
    assert outcome.seconds < 2 and peak < 16 * 2**20


def test_a_huge_bomb_is_counted_without_huge_numbers() -> None:
    error = compile_checked(_doubling(MAX_BLOCK_DEPTH - 1)).first_error()
    assert "the whole mission: at least 1 000 000 000 000 000" in error.message


def test_the_count_is_the_mission_tree_size() -> None:
    """Counting matches building exactly (but for Exit blocks shared by siblings)."""
    for path in mission_files():
        # The mission as the tree is built from: loops, groups and libraries expanded.
        mission = compile_file(path).mission
        amt = build_mission_tree(mission)
        counted = _BlockSizes(mission).size[mission.entry] + 1  # + the initial node
        shared = sum(1 for _, _, r in amt.edges(data="role") if r == "exit") - sum(
            1 for n in amt if sum(1 for _, _, r in amt.in_edges(n, data="role") if r == "exit")
        )
        assert (
            (counted == amt.number_of_nodes()) if not shared else counted >= amt.number_of_nodes()
        )


def test_a_mission_at_the_size_limit_compiles_and_one_more_node_does_not() -> None:
    at_limit = _main(*["D1.FlyByX(1)"] * (MAX_TREE_NODES - 1))  # + the block itself
    assert block_limit_errors(parse_mission(at_limit)) == []
    over = _main(*["D1.FlyByX(1)"] * MAX_TREE_NODES)
    error = compile_checked(over).first_error()
    assert "block 'SEQ_Main' expands to 50 001 mission-tree nodes" in error.message
    compiled = compile_checked(at_limit).compiled
    assert compiled is not None and compiled.amt.number_of_nodes() == MAX_TREE_NODES + 1


def test_fleet_size_limit() -> None:
    def fleet(n: int) -> str:
        return "func PAR_Main() {\n" + "".join(f"\tD{i}.Arm()\n" for i in range(n)) + "}\n"

    assert compile_checked(fleet(MAX_DRONES)).compiled is not None
    text = fleet(MAX_DRONES + 1)
    error = compile_checked(text).first_error()
    assert "more than 1 000 drones; 'D1000' is one too many" in error.message
    assert caret_text(text, error) == "D1000"


# -- printing many diagnostics is linear -----------------------------------------------------


def test_twenty_thousand_warnings_print_in_linear_time() -> None:
    text = "".join(f"func B{i}() {{\n\tD1.Arm()\n}}\n" for i in range(10_000))
    outcome = compile_checked(text)
    assert outcome.compiled is not None
    warnings = outcome.compiled.warnings
    assert len(warnings) == 2 * 10_000 - 1
    start = time.process_time()
    one_by_one = "\n".join(w.render("w.go", text) for w in warnings)  # as the CLI prints them
    assert time.process_time() - start < 5  # was 82 s (the source split once per warning)
    start = time.process_time()
    assert render_diagnostics(warnings, "w.go", text) == one_by_one
    assert time.process_time() - start < 5


def test_a_long_line_prints_a_window_around_each_mistake() -> None:
    text = "func SEQ_M() { " + "; ".join(f"D1.Foo{i}()" for i in range(20_000)) + " }\n"
    outcome = compile_checked(text)
    assert outcome.error is not None and len(outcome.error.diagnostics) == 20_000
    start = time.process_time()
    rendered = outcome.error.render("long.go", text).splitlines()
    assert time.process_time() - start < 5
    assert max(len(line) for line in rendered) < 200
    index = next(i for i, line in enumerate(rendered) if "unknown action 'Foo15000'" in line)
    excerpt, caret = rendered[index + 1], rendered[index + 2]
    assert excerpt.startswith("    ...") and excerpt.endswith("...")
    assert excerpt[caret.index("^") :].startswith("Foo15000")
    assert caret.strip() == "^" + "~" * (len("Foo15000") - 1)


# -- lines and columns: characters, one line definition ---------------------------------------


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"], ids=["lf", "crlf", "cr-only"])
@pytest.mark.parametrize(
    "prefix",
    [
        "",
        "// a leading comment\n",
        "// " + DRON + " \u7121\u4eba\u6a5f " + A4 + "\n",
        "/* form\ffeed and\vvertical tab */\n",
        "// U+2028 \u2028 and U+0085 \x85 in a comment\n",
    ],
    ids=["plain", "comment", "unicode", "ff-vt", "separators-in-comment"],
)
def test_locations_are_lines_and_characters(newline: str, prefix: str) -> None:
    body = f"package Odd\n\nfunc SEQ_Main() {{\n\t{DRON}.Arm()\n\t{A4}{A4}.Fly(1)\n}}\n"
    text = (prefix + body).replace("\n", newline)
    error = compile_checked(text).first_error()
    assert error.message == "unknown action 'Fly'"
    assert error.loc.line == prefix.count("\n") + 5
    assert error.loc.col == 5  # tab, two four-byte letters, the dot
    assert caret_text(text, error) == "Fly"
    rendered = MissionError([error]).render("odd.go", text).splitlines()
    assert rendered[1] == f"        {A4}{A4}.Fly(1)"
    assert rendered[2] == "           ^~~"


def test_a_cr_only_file_with_a_leading_comment_compiles() -> None:
    text = "// first line\rpackage CrOnly\rfunc SEQ_Main() {\r\tD1.Arm()\r}\r"
    compiled = compile_checked(text).compiled
    assert compiled is not None and compiled.mission.name == "CrOnly"


@pytest.mark.parametrize("odd", ["\u2028", "\u2029", "\x85"])
def test_a_line_separator_in_code_is_an_error_on_its_line(odd: str) -> None:
    text = _main("D1.Arm()", odd + "D1.Land()")
    error = compile_checked(text).first_error()
    assert (error.loc.line, error.loc.col) == (3, 2)
    assert caret_text(text, error).startswith(odd)


def test_form_feed_and_vertical_tab_are_whitespace_within_a_line() -> None:
    text = "func SEQ_Main() {\f\v\n\tD1.Arm()\f\n\tD1.Fly()\n}\n"
    error = compile_checked(text).first_error()
    assert (error.loc.line, error.loc.col) == (3, 5)


# -- names become file names: capped ----------------------------------------------------------


@pytest.mark.parametrize(
    ("text", "name"),
    [
        (_main("D" * 300 + ".Arm()"), "D" * 300),
        ("var " + "Д" * 65 + " Quadcopter\n" + _main("D1.Arm()"), "Д" * 65),
        (_main(A4 * 33 + ".Arm()"), A4 * 33),  # 33 characters, 132 bytes
        ("func SEQ_" + "x" * 100 + "() {\n\tD1.Arm()\n}\n", "SEQ_" + "x" * 100),
        ("package " + "P" * 70 + "\n" + _main("D1.Arm()"), "P" * 70),
        (_main("D1.Arm()", "SEQ_" + "y" * 80 + "()"), "SEQ_" + "y" * 80),
        (_condition("X" * 65 + ".Z() > 1"), "X" * 65),
        ("package " + COMBINING + "\n" + _main("D1.Arm()"), COMBINING),
        (_main(COMBINING + ".Arm()"), COMBINING),
    ],
)
def test_long_names_are_located_errors(text: str, name: str) -> None:
    errors = [d for d in compile_checked(text).diagnostics if "the name" in d.message]
    assert errors, "no name error"
    assert caret_text(text, errors[0]) == name
    assert "limit of" in errors[0].message


def test_names_at_the_limit_and_long_words_elsewhere_are_fine() -> None:
    name = "D" * MAX_NAME_CHARS
    text = f"// {'w' * 500}\nvar {name} Quadcopter\n" + _main(f"{name}.Arm()")
    compiled = compile_checked(text).compiled
    assert compiled is not None and name in compiled.programs
    cyrillic = "Д" * MAX_NAME_CHARS  # 128 bytes exactly
    assert compile_checked(_main(f"{cyrillic}.Arm()")).compiled is not None


# -- forks: all-to-all synchronisation is quadratic, counted before slicing ---------------------


def _par_rounds(drones: int, rounds: int, between: str = "") -> str:
    """``rounds`` PAR blocks of ``drones`` drones in a row (each waits for all of the last)."""
    steps = "".join(f"\tPAR_All()\n{between}" for _ in range(rounds))
    branches = "".join(f"\tD{i}.FlyByX(1)\n" for i in range(drones))
    return f"func SEQ_Main() {{\n{steps}}}\nfunc PAR_All() {{\n{branches}}}\n"


def _sync_error(text: str) -> object:
    mission = parse_mission(text)
    return _sync_arcs_error(_MegIndex(build_execution_graph(build_mission_tree(mission))))


def test_back_to_back_par_blocks_of_many_drones_are_refused_before_slicing() -> None:
    text = _par_rounds(1000, 10)  # 9 million arcs: GBs if sliced
    tracemalloc.start()
    try:
        outcome = compile_checked(text)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    error = outcome.first_error()
    assert error.message.startswith(
        "block 'PAR_All' starts 1000 drones right after 1000 parallel branches end"
    )
    assert "(1 000 000 arcs; 9 001 000 in the whole mission" in error.message
    assert caret_text(text, error) == "PAR_All" and error.loc.line == 13
    assert "PauseFor(0)" in error.hint
    assert outcome.seconds < 5 and peak < 128 * 2**20


def test_the_sync_arc_limit_is_exact_and_the_hint_works() -> None:
    # 315 + 315 * 315 = 99 540 arcs; 316 drones: 100 172 > MAX_SYNC_ARCS.
    assert MAX_SYNC_ARCS == 100_000
    assert _sync_error(_par_rounds(315, 2)) is None
    assert _sync_error(_par_rounds(316, 2)) is not None
    hinted = compile_checked(_par_rounds(316, 3, between="\tD0.PauseFor(0)\n"))
    assert hinted.compiled is not None


# -- junk: bounded work, a located refusal (issue 28) --------------------------------------------


def _junk(size: int, seed: int = 28) -> str:
    """``size`` characters of printable junk (the issue's 2 MB file took 9.4 CPU-s)."""
    import random
    import string

    rng = random.Random(seed)
    return "".join(rng.choices(string.printable, k=size))


def test_a_junk_file_is_refused_after_reading_its_first_64_kib_at_its_first_error() -> None:
    text = _junk(MAX_SOURCE_BYTES - 1000)
    outcome = compile_checked(text, "junk.go")
    errors = [d for d in outcome.diagnostics if d.severity == "error"]
    assert len(errors) == 1, len(errors)  # not 200 000 of them
    assert "is not mission text: more than 100 errors in its first" in errors[0].message
    assert errors[0].loc.line == 1
    # Reading the first 64 KiB costs a fraction of the whole: the rest is never parsed.
    head = compile_checked(text[:PROBE_BYTES], "head.go")
    assert len([d for d in head.diagnostics if d.severity == "error"]) == MAX_ERRORS + 1


def test_junk_after_a_valid_start_reports_the_first_100_errors_and_counts_the_rest() -> None:
    body = "".join(f"\tD1.FlyByX({i % 7})\n" for i in range(6000))
    assert len(body) > PROBE_BYTES  # the junk starts past what the probe reads
    text = "func SEQ_Main() {\n" + body + "}\n" + _junk(500_000)
    outcome = compile_checked(text, "mixed.go")
    errors = [d for d in outcome.diagnostics if d.severity == "error"]
    assert len(errors) == MAX_ERRORS + 1
    last = max(errors, key=lambda d: (d.loc.line, d.loc.col))
    assert "more errors from here on are not shown (only the first 100 are)" in last.message


def test_a_long_mission_is_not_taken_for_junk() -> None:
    body = "".join(f"\tD1.FlyByX({i % 7}) // step {i} of a long flight\n" for i in range(4000))
    text = "func SEQ_Main() {\n" + body + "}\n"
    assert len(text.encode()) > 2 * PROBE_BYTES  # the probe cuts it inside the block
    assert compile_checked(text).compiled is not None
