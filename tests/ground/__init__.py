"""Tests of the ground station package (eamos.ground)."""
