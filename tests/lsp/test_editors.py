"""The editor set-ups in the repository hold together: the VS Code extension's files exist, its
client is valid JavaScript starting `eamos lsp`, its keywords are the vocabulary's, and the
documented set-ups name the same command."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pytest

from eamos.program.uniform import CONTROL_STRUCTURES

from .lsp_helpers import REPO

VSCODE = REPO / "editors" / "vscode"


def test_the_extension_names_only_files_it_ships() -> None:
    manifest = json.loads((VSCODE / "package.json").read_text(encoding="utf-8"))
    contributes = manifest["contributes"]
    paths = [manifest["main"], *(lang["configuration"] for lang in contributes["languages"])]
    paths += [g["path"] for g in contributes["grammars"]]
    paths += [s["path"] for s in contributes["snippets"]]
    for path in paths:
        assert (VSCODE / path).is_file(), path
    (language,) = contributes["languages"]
    assert "**/missions/**/*.go" in language["filenamePatterns"]
    assert {s["language"] for s in contributes["snippets"]} == {language["id"]}


def test_the_grammar_highlights_the_vocabularys_control_structures() -> None:
    grammar = json.loads((VSCODE / "syntaxes" / "eamos.tmLanguage.json").read_text())
    match = grammar["patterns"][0]["match"]
    words = re.search(r"\(([^()]*)\)", match)
    assert words is not None and set(words.group(1).split("|")) == set(CONTROL_STRUCTURES)


def test_the_client_starts_eamos_lsp_and_is_valid_javascript() -> None:
    source = (VSCODE / "extension.js").read_text(encoding="utf-8")
    assert '"lsp"' in source and "TransportKind.stdio" in source
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed: cannot check extension.js's syntax")
    subprocess.run([node, "--check", str(VSCODE / "extension.js")], check=True, timeout=60)


def test_the_editor_guide_covers_four_editors_with_the_same_command() -> None:
    guide = (REPO / "docs" / "editors.md").read_text(encoding="utf-8")
    for editor in ("VS Code", "Neovim", "Helix", "Emacs"):
        assert f"## {editor}" in guide, editor
    assert guide.count("eamos lsp") >= 2
    assert '"lsp"' in guide  # the command as the configurations write it
