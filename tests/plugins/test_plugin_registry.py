"""Action plugins: declarations, discovery through entry points, the typed command, the actor.

Discovery is tested for real: the test lab package is installed into a temporary folder
with its ``dist-info`` (tests/plugins/lab.py), and importlib.metadata must find it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from eamos.hal import ActionResult
from eamos.hal.fake import FakeAdapter
from eamos.hal.sim import camera
from eamos.program.camera import CAMERA_PLUGINS, GIMBAL
from eamos.program.plugins import (
    EMPTY_PLUGINS,
    ActionPlugin,
    PluginError,
    PluginRegistry,
    discover_plugins,
)
from eamos.program.uniform import CommandError, PluginAction, decode_command
from tests.actors.test_uniform_api import Rig

from .lab import install_lab


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Callable[..., Rig]]:
    made: list[Rig] = []

    def factory(adapter: Any) -> Rig:
        made.append(Rig(adapter, tmp_path / adapter.drone))
        return made[-1]

    yield factory
    for r in made:
        r.stop()


@pytest.mark.parametrize(
    ("plugin", "problem"),
    [
        (ActionPlugin("spray", (), "d"), "not a CamelCase identifier"),
        (ActionPlugin("Takeoff", (), "d"), "is a uniform action"),
        (ActionPlugin("Spray", ("duration",), "d"), "ending in its unit"),
        (ActionPlugin("Spray", ("a_s", "a_s"), "d"), "parameter names repeat"),
        (ActionPlugin("Spray", (), "d", {"ros": "m:f"}), "unknown adapter family 'ros'"),
        (ActionPlugin("Spray", (), "d", {"sim": "m.f"}), "'module:callable'"),
        (ActionPlugin("Spray", ("a_s",), "d", ranges={"b_s": (0, 1)}), "unknown parameter"),
        (ActionPlugin("Spray", ("a_s",), "d", ranges={"a_s": (2, 1)}), "low <= high"),
    ],
)
def test_a_bad_declaration_says_what_is_wrong(plugin: ActionPlugin, problem: str) -> None:
    assert any(problem in p for p in plugin.problems()), plugin.problems()


def test_the_camera_plugins_are_well_declared_and_installed_through_entry_points() -> None:
    for plugin in CAMERA_PLUGINS:
        assert plugin.problems() == []
        assert plugin.families == ("sim", "mavlink")
    installed = discover_plugins()
    assert installed.problems == ()
    for plugin in CAMERA_PLUGINS:
        assert installed.get(plugin.name) == plugin  # pyproject.toml's entry points


def test_a_plugin_action_decodes_with_the_plugins_parameter_list() -> None:
    specs = PluginRegistry([GIMBAL]).specs()
    command = decode_command("Gimbal", [-30], specs)
    assert command == PluginAction("Gimbal", ("pitch_deg",), (-30.0,))
    assert (command.action, command.args, command.moves) == ("Gimbal", (-30.0,), False)
    assert isinstance(command, PluginAction) and command.value("pitch_deg") == -30.0
    with pytest.raises(CommandError, match="takes 1 argument"):
        decode_command("Gimbal", [], specs)
    with pytest.raises(CommandError, match="must be finite"):
        decode_command("Gimbal", [float("nan")], specs)
    with pytest.raises(CommandError, match="unknown action 'Gimbal'"):
        decode_command("Gimbal", [-30])  # without plugins it is not an action


def test_an_implementation_is_loaded_on_demand_and_a_missing_one_is_a_clear_error() -> None:
    registry = PluginRegistry(CAMERA_PLUGINS)
    assert registry.implemented_by("sim") == {"TakePhoto", "StartVideo", "StopVideo", "Gimbal"}
    assert registry.implemented_by("ground") == frozenset()
    assert registry.implementation("TakePhoto", "sim") is camera.take_photo
    with pytest.raises(PluginError, match="no 'ground' implementation"):
        registry.implementation("TakePhoto", "ground")
    with pytest.raises(PluginError, match="no plugin provides action 'Spray'"):
        registry.implementation("Spray", "sim")
    with pytest.raises(PluginError, match="cannot load"):
        PluginRegistry(
            [ActionPlugin("Spray", (), "d", {"sim": "eamos_no_such_module:f"})]
        ).implementation("Spray", "sim")


def test_discovery_finds_a_package_installed_with_an_entry_point(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.syspath_prepend(str(install_lab(tmp_path / "site")))
    found = discover_plugins()
    spray = found.get("Spray")
    assert spray is not None, found.problems
    assert spray.params == ("duration_s",) and spray.families == ("sim",)
    assert found.implemented_by("sim") >= {"Spray", "TakePhoto"}
    assert found.implemented_by("mavlink") == {"TakePhoto", "StartVideo", "StopVideo", "Gimbal"}


def test_broken_entry_points_are_reported_not_raised(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    entry_points = (
        "[eamos.actions]\n"
        "Missing = eamos_no_such_module:X\n"
        "NotAPlugin = eamos_labspray.sim:spray\n"
        "Renamed = eamos_labspray:SPRAY\n"
    )
    monkeypatch.syspath_prepend(str(install_lab(tmp_path / "site", entry_points)))
    found = discover_plugins()
    assert {"Missing", "NotAPlugin", "Renamed", "Spray"}.isdisjoint(found.plugins)
    problems = "\n".join(found.problems)
    assert "'Missing'" in problems and "does not load" in problems
    assert "'NotAPlugin'" in problems and "not an ActionPlugin" in problems
    assert "'Renamed'" in problems and "names action 'Spray'" in problems
    assert found.get("TakePhoto") is not None  # the others still work


def test_a_subprocess_with_the_package_on_pythonpath_finds_it(tmp_path: Path) -> None:
    site = install_lab(tmp_path / "site")
    code = (
        "from eamos.program.plugins import discover_plugins; "
        "print(sorted(discover_plugins().implemented_by('sim')))"
    )
    env = dict(os.environ, PYTHONPATH=str(site))
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert "'Spray'" in out.stdout
    bare = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "'Spray'" not in bare.stdout


def test_the_uniform_api_decodes_plugin_actions_with_its_adapters_plugins(
    rig: Callable[..., Rig],
) -> None:
    fake = FakeAdapter("D1", auto=True, plugins=PluginRegistry(CAMERA_PLUGINS))
    r = rig(fake)
    assert r.call("g", "Gimbal", -20.0).result == ActionResult("ok")
    (call,) = fake.calls_of("run")
    assert call.command == PluginAction("Gimbal", ("pitch_deg",), (-20.0,))
    bad = r.call("g2", "Gimbal")
    assert bad.result.status == "failed" and "takes 1 argument" in bad.result.reason
    assert len(fake.calls_of("run")) == 1  # never reached the adapter
    plain = FakeAdapter("D2", auto=True)
    assert plain.plugins is EMPTY_PLUGINS
    unknown = rig(plain).call("p", "TakePhoto")
    assert unknown.result == ActionResult("failed", "unknown action 'TakePhoto'")


def test_the_plugin_guide_shows_the_test_lab_package() -> None:
    """docs/plugins.md's example is the package these tests install (line for line)."""
    repo = Path(__file__).resolve().parents[2]
    guide = (repo / "docs" / "plugins.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", guide, re.S)
    package = repo / "tests" / "plugins" / "lab_package" / "eamos_labspray"
    for block, name in zip(blocks, ("__init__.py", "sim.py"), strict=True):
        source = (package / name).read_text(encoding="utf-8").splitlines()
        code = [ln for ln in block.splitlines() if ln.strip() and not ln.startswith("#")]
        assert code and all(ln in source for ln in code), name
