"""Command-line code: every console entry point, one exit-code table, shared option builders."""
