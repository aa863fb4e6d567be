"""The editor set-ups in the repository hold together: the VS Code extension's files exist, its
client is valid JavaScript starting `eamos lsp`, its keywords are the vocabulary's, the
documented set-ups name the same command; a headless Neovim with docs/editors.md's set-up gets
the compiler's diagnostics from `eamos lsp`, and `vsce package` packages the extension."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

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


# -- Neovim, with the guide's init.lua -----------------------------------------------------

GUIDE = REPO / "docs" / "editors.md"
#: Waits (Neovim's own event loop, not a sleep) for the diagnostics, writes them, quits.
PROBE = """\
local ok = vim.wait(90000, function() return #vim.diagnostic.get(0) > 0 end, 50)
local found = {}
for _, d in ipairs(vim.diagnostic.get(0)) do
  table.insert(found, { lnum = d.lnum, col = d.col, message = d.message })
end
local result = { ok = ok, filetype = vim.bo.filetype, diagnostics = found }
vim.fn.writefile({ vim.fn.json_encode(result) }, vim.env.EAMOS_PROBE_OUT)
vim.cmd("qa!")
"""
#: Parses a Lua file with the installed Neovim's Lua, and says whether it parsed.
PARSE = """\
local chunk, err = loadstring(table.concat(vim.fn.readfile(vim.env.EAMOS_LUA), "\\n"))
vim.fn.writefile({ chunk and "parsed" or ("error: " .. err) }, vim.env.EAMOS_PROBE_OUT)
vim.cmd("qa!")
"""


def neovim_blocks() -> list[tuple[tuple[int, int], str]]:
    """The guide's Neovim set-ups: (the version it is for, its Lua), in order."""
    text = GUIDE.read_text(encoding="utf-8")
    section = text[text.index("## Neovim") : text.index("## Helix")]
    blocks = []
    for heading, code in re.findall(
        r"\*\*Neovim (\d+\.\d+)[^*]*\*\*.*?```lua\n(.*?)```", section, re.S
    ):
        major, minor = (int(x) for x in heading.split("."))
        blocks.append(((major, minor), code))
    return blocks


def neovim_version(nvim: str) -> tuple[int, int]:
    first = subprocess.run(
        [nvim, "--version"], capture_output=True, text=True, timeout=60, check=True
    ).stdout.splitlines()[0]
    found = re.search(r"v(\d+)\.(\d+)", first)
    assert found is not None, first
    return int(found.group(1)), int(found.group(2))


def headless_neovim(nvim: str, tmp: Path, init: str, script: str, *files: str, **env: str) -> str:
    """Run a headless Neovim with ``init`` as its init.lua and ``script`` after the file opens."""
    (tmp / "init.lua").write_text(init, encoding="utf-8")
    (tmp / "probe.lua").write_text(script, encoding="utf-8")
    out = tmp / "probe.out"
    home = tmp / "home"
    environment = {
        **os.environ,
        "HOME": str(home),
        "XDG_CONFIG_HOME": str(home / ".config"),
        "XDG_DATA_HOME": str(home / ".local" / "share"),
        "XDG_STATE_HOME": str(home / ".local" / "state"),
        "XDG_CACHE_HOME": str(home / ".cache"),
        # `eamos` as the guide writes it: the one installed with this Python, on PATH.
        "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
        "EAMOS_PROBE_OUT": str(out),
        **env,
    }
    proc = subprocess.run(
        [nvim, "--headless", "-n", "-i", "NONE", "-u", str(tmp / "init.lua"), *files,
         "-c", f"luafile {tmp / 'probe.lua'}"],
        cwd=tmp,
        env=environment,
        capture_output=True,
        text=True,
        timeout=180,
    )  # fmt: skip
    assert out.is_file(), f"Neovim wrote nothing: {proc.returncode} {proc.stdout} {proc.stderr}"
    return out.read_text(encoding="utf-8").strip()


def test_the_guide_has_a_set_up_for_old_and_new_neovims() -> None:
    versions = [v for v, _ in neovim_blocks()]
    assert versions == [(0, 7), (0, 11)]


@pytest.mark.parametrize("index", [0, 1], ids=["neovim-0.7", "neovim-0.11"])
def test_a_headless_neovim_with_the_guides_set_up_gets_the_compilers_diagnostic(
    index: int, tmp_path: Path
) -> None:
    """The set-up runs as written where the installed Neovim is recent enough for it.

    Where it is older (Debian 12's 0.7.2 and the 0.11 set-up) the installed Neovim's Lua
    parses the block instead: its syntax is checked, its calls are not.
    """
    nvim = shutil.which("nvim")
    if nvim is None:
        pytest.skip("Neovim (nvim) is not installed: apt-get install neovim")
    needs, init = neovim_blocks()[index]
    if neovim_version(nvim) < needs:
        (tmp_path / "setup.lua").write_text(init, encoding="utf-8")
        parsed = headless_neovim(nvim, tmp_path, "", PARSE, EAMOS_LUA=str(tmp_path / "setup.lua"))
        assert parsed == "parsed"
        return
    missions = tmp_path / "missions"
    missions.mkdir()
    (missions / "bad.go").write_text(
        "var Drone1 Quadcopter\nfunc SEQ_Main() {\n    Drone1.Takof(1)\n}\n", encoding="utf-8"
    )
    result = json.loads(headless_neovim(nvim, tmp_path, init, PROBE, "missions/bad.go"))
    assert result["filetype"] == "eamos"
    assert result["ok"], result
    (diagnostic,) = result["diagnostics"]
    assert (diagnostic["lnum"], diagnostic["col"]) == (2, 11)  # 0-based: line 3, column 12
    assert diagnostic["message"].startswith("unknown action 'Takof'")
    assert "did you mean Takeoff?" in diagnostic["message"]


# -- VS Code: the package ------------------------------------------------------------------


def test_vsce_packages_the_extension(tmp_path: Path) -> None:
    """``npm install`` then the guide's ``npx @vscode/vsce package ...`` in a copy of the folder.

    npm keeps what it downloads in its cache (``npm config get cache``, ``~/.npm``), and is
    asked to prefer it: a second run reads the registry only for what changed.
    """
    npm, npx = shutil.which("npm"), shutil.which("npx")
    if shutil.which("node") is None or npm is None or npx is None:
        pytest.skip("node and npm are not installed: apt-get install nodejs npm")
    guide = GUIDE.read_text(encoding="utf-8")
    (command,) = re.findall(r"^(npx @vscode/vsce package[^#\n]*?)\s*#", guide, re.M)
    folder = tmp_path / "vscode"
    shutil.copytree(VSCODE, folder, ignore=shutil.ignore_patterns("node_modules", "*.vsix"))
    install = subprocess.run(
        [npm, "install", "--no-audit", "--no-fund", "--prefer-offline"],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert install.returncode == 0, install.stdout + install.stderr
    package = subprocess.run(
        [npx, "--no-install", *command.split()[1:]],
        cwd=folder,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=600,
    )
    output = package.stdout + package.stderr
    assert package.returncode == 0, output
    assert "ERROR" not in output and "will be broken" not in output
    manifest = json.loads((VSCODE / "package.json").read_text(encoding="utf-8"))
    vsix = folder / f"{manifest['name']}-{manifest['version']}.vsix"
    with zipfile.ZipFile(vsix) as archive:
        names = set(archive.namelist())
    assert {"extension/extension.js", "extension/package.json", "extension/LICENSE.txt"} <= names
    assert any(n.startswith("extension/node_modules/vscode-languageclient/") for n in names)


def test_the_extensions_license_is_the_projects() -> None:
    assert (VSCODE / "LICENSE").read_text() == (REPO / "LICENSE").read_text()
