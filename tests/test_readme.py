"""The README's promises: its two commands, and its example mission."""

from __future__ import annotations

import re
from pathlib import Path

from eamos.compiler import compile_mission

REPO = Path(__file__).resolve().parents[1]


def readme_commands() -> list[str]:
    text = (REPO / "README.md").read_text()
    block = re.search(r"```bash\n(.*?)```", text, re.S)
    assert block is not None, "the README starts with a bash block of two commands"
    return [line for line in block.group(1).splitlines() if line.strip()]


def test_readme_starts_with_two_commands_and_ci_runs_the_test_command():
    first, second = readme_commands()
    assert "eamos run missions/" in first and "pytest" in second
    mission = first.split("eamos run ")[1].split()[0]
    assert (REPO / mission).exists()
    ci = (REPO / ".ci" / "run").read_text()
    assert second in ci.splitlines(), ".ci/run must run the README's test command verbatim"


def test_readme_example_mission_compiles():
    text = (REPO / "README.md").read_text()
    block = re.search(r"```go\n(.*?)```", text, re.S)
    assert block is not None
    compiled = compile_mission(block.group(1), "readme.go")
    assert set(compiled.programs) == {"GCS", "Drone1", "Drone2"}
