"""A drone loads and runs its program without the compiler, tree-sitter or networkx."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from eamos.compiler import compile_file

from .fleet_harness import WAIT_S

CHILD = r"""
import importlib.abc, sys

class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('tree_sitter', 'tree_sitter_go', 'networkx') \
                or name.startswith('eamos.compiler'):
            raise ImportError(f'{name} must not be needed on a drone')
        return None

sys.meta_path.insert(0, Block())
from pathlib import Path
import eamos.cli.node  # everything eamos-node imports
import eamos.actors.drone
from eamos.actors.runtime import DroneRuntime, NetSettings
from eamos.hal.fake import FakeAdapter
from eamos.program.format import load_program

program = load_program(Path(sys.argv[1]))
runtime = DroneRuntime(program, FakeAdapter(program.drone, auto=True),
                       NetSettings('tcp://127.0.0.1:0', {}), None)
runtime.start()
runtime.stop()
print('ran', program.drone, len(program.native_nodes()))
"""


def test_program_runs_without_compiler_modules(tmp_path):
    compiled = compile_file(Path(__file__).parents[2] / "missions" / "experiment_b.go")
    path = compiled.programs["Drone1"].save(tmp_path / "Drone1.program.json")
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, str(path)], capture_output=True, text=True, timeout=WAIT_S
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("ran Drone1")
