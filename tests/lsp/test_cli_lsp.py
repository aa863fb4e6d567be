"""``eamos lsp`` as a command: help, a clean exit when the editor closes the pipe, and one log
line (no traceback) for a malformed message."""

from __future__ import annotations

import subprocess
import sys

LSP = [sys.executable, "-m", "eamos.cli", "lsp"]


def test_help_names_the_editor_guide() -> None:
    out = subprocess.run([*LSP, "--help"], capture_output=True, text=True, timeout=120, check=True)
    assert "docs/editors.md" in out.stdout


def test_end_of_input_ends_the_server_cleanly() -> None:
    done = subprocess.run([*LSP, "--stdio"], input=b"", capture_output=True, timeout=120)
    assert done.returncode == 0, done.stderr


def test_a_malformed_message_is_one_log_line_without_a_traceback() -> None:
    bad = b"Content-Length: 5\r\n\r\n{bad}"
    done = subprocess.run(LSP, input=bad, capture_output=True, timeout=120)
    assert done.returncode == 0
    stderr = done.stderr.decode()
    assert "Traceback" not in stderr and "a body that is not JSON" in stderr
    assert len(stderr.strip().splitlines()) == 1, stderr
    assert b"window/showMessage" in done.stdout  # and the editor is told
    assert b'"id": null, "error": {"code": -32700' in done.stdout  # with a parse error
    verbose = subprocess.run([*LSP, "-v"], input=bad, capture_output=True, timeout=120)
    assert "Traceback" in verbose.stderr.decode()


def test_importing_the_analysis_loads_no_protocol_library() -> None:
    code = "import sys, eamos.lsp; print(any(m in sys.modules for m in ('pygls', 'lsprotocol')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "False"
