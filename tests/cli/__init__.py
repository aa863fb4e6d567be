"""Tests of the command-line package (eamos/cli)."""
