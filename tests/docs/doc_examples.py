"""The examples of the README and docs/*.md, read from the markdown (pure: text in, records out).

Two kinds of example:

* a **mission**: every fenced block marked ```go;
* a **command**: every line of a shell block (```sh, ```bash, ```console) whose command is
  ``eamos`` or one of its siblings (``eamos-node``, ``eamos-sim-vehicle``), written bare, after a
  ``$ `` prompt, as ``.venv/bin/eamos`` or after ``&&``.  Comments (``# ...``) are dropped.

An HTML comment on the line right before a block (blank lines between allowed) tells the test
what to expect of the block's examples; without one a mission must compile, pass ``eamos check``
and, when it declares drones and has an entry block, fly; a command must exit 0::

    <!-- doc-test: fragment -->                        part of a mission: syntax only
    <!-- doc-test: syntax-only (needs SSH) -->         needs hardware, SSH, a browser, a
                                                        plugin: syntax only (a mission is
                                                        parsed, a command's arguments parsed)
    <!-- doc-test: exit 2; as bad.go; output -->       a mission refused by ``eamos compile``
                                                        (or a command) with this exit code;
                                                        ``as``: the file name the doc gives it;
                                                        ``output``: the next ```text block is
                                                        what the command prints
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path

SHELL_LANGUAGES = frozenset({"sh", "bash", "console", "shell"})
#: The console entry points of pyproject.toml.
COMMANDS = frozenset({"eamos", "eamos-node", "eamos-sim-vehicle"})
MARKER = re.compile(r"<!--\s*doc-test:\s*(.*?)\s*-->")
FENCE = re.compile(r"^(\s*)```\s*([\w+-]*)\s*$")


class MarkerError(ValueError):
    """A doc-test marker the test does not understand (a typo would silently weaken a test)."""


@dataclass(frozen=True)
class Expectation:
    """What a marker says of its block's examples."""

    syntax_only: bool = False
    reason: str = ""
    exit_code: int = 0
    file_name: str = ""
    output: str | None = None  # the text the command prints, when the marker says ``output``


@dataclass(frozen=True)
class Block:
    """One fenced block: its language, first line of content (1-based) and text."""

    doc: str
    line: int
    language: str
    text: str
    expect: Expectation = field(default_factory=Expectation)


@dataclass(frozen=True)
class Mission:
    """A mission block."""

    doc: str
    line: int
    text: str
    expect: Expectation

    @property
    def ident(self) -> str:
        return f"{self.doc}:{self.line}"


@dataclass(frozen=True)
class Command:
    """One command line; ``before``: the block's earlier commands, run first in the same folder."""

    doc: str
    line: int
    argv: tuple[str, ...]
    expect: Expectation
    before: tuple[tuple[str, ...], ...] = ()

    @property
    def ident(self) -> str:
        return f"{self.doc}:{self.line}"

    @property
    def text(self) -> str:
        return shlex.join(self.argv)


def _split_outside_brackets(text: str) -> list[str]:
    """``text`` split at each ``;`` that is not inside brackets (a reason may hold one)."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(text):
        depth += {"(": 1, ")": -1}.get(char, 0)
        if char == ";" and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    return [*parts, text[start:]]


def parse_marker(text: str) -> Expectation:
    """The expectation a marker's text (``fragment``, ``exit 2; as bad.go``...) states."""
    syntax_only, reason, exit_code, file_name, output = False, "", 0, "", False
    for part in (p.strip() for p in _split_outside_brackets(text)):
        word, _, rest = part.partition(" ")
        rest = rest.strip()
        if word == "fragment":
            syntax_only, reason = True, "a fragment of a mission"
        elif word == "syntax-only":
            if not (rest.startswith("(") and rest.endswith(")")):
                raise MarkerError(f"syntax-only needs a reason in brackets: {text!r}")
            syntax_only, reason = True, rest[1:-1]
        elif word == "exit" and rest.isdigit():
            exit_code = int(rest)
        elif word == "as" and rest:
            file_name = rest
        elif word == "output" and not rest:
            output = True
        else:
            raise MarkerError(f"unknown doc-test marker: {part!r} in {text!r}")
    return Expectation(syntax_only, reason, exit_code, file_name, "" if output else None)


def blocks(doc: str, text: str) -> list[Block]:
    """Every fenced block of a markdown text, with the marker before it (if any)."""
    lines = text.split("\n")
    found: list[Block] = []
    marker: Expectation | None = None
    i = 0
    while i < len(lines):
        line = lines[i]
        if m := MARKER.fullmatch(line.strip()):
            marker = parse_marker(m.group(1))
        elif m := FENCE.match(line):
            end = i + 1
            while end < len(lines) and not re.match(r"^\s*```\s*$", lines[end]):
                end += 1
            indent = len(m.group(1))
            body = "\n".join(ln[indent:] for ln in lines[i + 1 : end])
            found.append(Block(doc, i + 2, m.group(2), body + "\n", marker or Expectation()))
            marker = None
            i = end
        elif line.strip():
            marker = None  # a marker belongs to the block right after it
        i += 1
    return _with_outputs(found)


def _with_outputs(found: list[Block]) -> list[Block]:
    # A marker saying ``output`` takes the next block's text as what the example prints.
    out = []
    for n, block in enumerate(found):
        if block.expect.output is not None:
            if n + 1 >= len(found) or found[n + 1].language not in ("text", ""):
                raise MarkerError(f"{block.doc}:{block.line}: 'output' but no text block follows")
            block = Block(
                block.doc,
                block.line,
                block.language,
                block.text,
                Expectation(
                    block.expect.syntax_only,
                    block.expect.reason,
                    block.expect.exit_code,
                    block.expect.file_name,
                    found[n + 1].text,
                ),
            )
        out.append(block)
    return out


def missions(doc: str, text: str) -> list[Mission]:
    """Every ```go block of a markdown text."""
    return [
        Mission(b.doc, b.line, b.text, b.expect) for b in blocks(doc, text) if b.language == "go"
    ]


def command_argv(line: str) -> tuple[str, ...] | None:
    """The ``eamos ...`` command of one shell line (``None`` if it runs no EAMOS command)."""
    line = line.strip()
    if line.startswith("$ "):
        line = line[2:]
    try:
        words = shlex.split(line, comments=True)
    except ValueError:
        return None
    # ``a && b``: the segment that runs an EAMOS command (the README's install-and-run line).
    segments: list[list[str]] = [[]]
    for word in words:
        if word == "&&":
            segments.append([])
        else:
            segments[-1].append(word)
    for segment in segments:
        if segment and Path(segment[0]).name in COMMANDS:
            return (Path(segment[0]).name, *segment[1:])
    return None


def commands(doc: str, text: str) -> list[Command]:
    """Every EAMOS command line of the shell blocks of a markdown text."""
    found: list[Command] = []
    for block in blocks(doc, text):
        if block.language not in SHELL_LANGUAGES:
            continue
        before: list[tuple[str, ...]] = []
        for offset, line in enumerate(block.text.split("\n")):
            argv = command_argv(line)
            if argv is None:
                continue
            found.append(Command(doc, block.line + offset, argv, block.expect, tuple(before)))
            before.append(argv)
    return found


def declares_drones(source: str) -> bool:
    """Whether a mission declares drones (``var D1 Quadcopter``, ``var Team [4]T``)."""
    return re.search(r"^\s*var\s+\w+\s+(\[\d+\]\s*)?\w", source, re.M) is not None


def inline_commands(doc: str, text: str) -> list[tuple[int, str]]:
    """``(line, text)`` of every EAMOS command quoted in prose (`` `eamos run X --speedup K` ``),
    outside fenced blocks: synopses and references, whose options must exist."""
    found = []
    in_block = False
    for number, line in enumerate(text.split("\n"), 1):
        if FENCE.match(line) or re.match(r"^\s*```\s*$", line):
            in_block = not in_block
            continue
        if not in_block:
            for span in re.findall(r"`((?:eamos|eamos-node|eamos-sim-vehicle) [^`]+)`", line):
                found.append((number, span))
    return found


def options_named(span: str) -> tuple[list[str], list[str]]:
    """The subcommand words (``["logs", "fetch"]``) and the options (``--fleet``) of a span."""
    words = span.replace("\\|", "|").split()[1:]
    subcommand = []
    for word in words:
        if not re.fullmatch(r"[a-z]+", word):
            break
        subcommand.append(word)
    return subcommand, re.findall(r"(?<![\w-])(--?[a-z][\w-]*)", span)
