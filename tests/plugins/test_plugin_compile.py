"""The compiler and the fleet against action plugins: table-driven checks, located errors.

In this process the installed plugins are the project's camera plugins (pyproject.toml's
entry points); the lab's ``Spray`` is seen only by subprocesses given its folder
(tests/plugins/lab.py), so the CLI cases also show that discovery works.
"""

from __future__ import annotations

import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from eamos.cli.adapter_actions import adapter_of
from eamos.compiler import MissionError, compile_mission
from eamos.compiler.drone_types import implemented_actions, plugin_argument_problem, vocabulary
from eamos.compiler.parse import parse_mission
from eamos.program.camera import CAMERA_PLUGINS
from eamos.program.plugins import ActionPlugin, PluginRegistry

from .lab import env_with, install_lab

MAIN = "func SEQ_A() {\n\tD1.Arm()\n\tD1.Takeoff(3)\n%s\n\tD1.Land()\n\tD1.Disarm()\n}\n"


def typed(methods: str, calls: str) -> str:
    """A mission with ``type T interface { Quadcopter; <methods> }`` and ``calls`` on D1."""
    return "type T interface {\n\tQuadcopter\n" + methods + "}\nvar D1 T\n" + MAIN % calls


@dataclass(frozen=True)
class Bad:
    name: str
    source: str
    where: str  # "line:col" of the first error
    message: str
    hint: str = ""


BAD = [
    Bad(
        "an action no plugin provides, called",
        typed("\tSpray(duration_s float64)\n", "\tD1.Spray(2)"),
        "9:5",
        "no adapter implements action 'Spray' yet",
    ),
    Bad(
        "a plugin action declared with other parameter names",
        typed("\tGimbal(yaw_deg float64)\n", "\tD1.Gimbal(10)"),
        "3:2",
        "action 'Gimbal' is provided by an installed plugin as Gimbal(pitch_deg float64)",
        "declare it as Gimbal(pitch_deg float64)",
    ),
    Bad(
        "a plugin action declared without its parameter",
        typed("\tGimbal()\n", "\tD1.Land()"),
        "3:2",
        "provided by an installed plugin as Gimbal(pitch_deg float64)",
    ),
    Bad(
        "a plugin action declared with a parameter it has not",
        typed("\tTakePhoto(count_count float64)\n", "\tD1.Land()"),
        "3:2",
        "provided by an installed plugin as TakePhoto()",
        "declare it as TakePhoto()",
    ),
    Bad(
        "a plugin action called with the wrong argument count",
        typed("\tGimbal(pitch_deg float64)\n", "\tD1.Gimbal()"),
        "9:2",
        "Gimbal takes 1 argument, got 0",
    ),
]


@pytest.mark.parametrize("case", BAD, ids=lambda c: c.name)
def test_plugin_mistakes_are_located(case: Bad) -> None:
    with pytest.raises(MissionError) as info:
        compile_mission(case.source, "m.go")
    first = next(d for d in info.value.diagnostics if d.severity == "error")
    assert f"{first.loc.line}:{first.loc.col}" == case.where, first
    assert case.message in first.message
    assert case.hint in first.hint


def test_installed_plugin_actions_compile_into_ordinary_action_nodes() -> None:
    source = typed(
        "\tTakePhoto()\n\tGimbal(pitch_deg float64)\n", "\tD1.Gimbal(-45)\n\tD1.TakePhoto()"
    )
    compiled = compile_mission(source, "m.go")
    actions = [(n.action, n.args) for n in compiled.programs["D1"].nodes if n.action]
    assert ("Gimbal", (-45.0,)) in actions and ("TakePhoto", ()) in actions
    assert not [w for w in compiled.warnings if "no adapter" in w.message]
    assert {"TakePhoto", "Gimbal", "Orbit"} <= implemented_actions()


def test_the_compiler_checks_against_the_registry_it_is_given() -> None:
    mission = parse_mission(typed("\tSpray(duration_s float64)\n", "\tD1.Land()"))
    spray = ActionPlugin("Spray", ("rate_s",), "d", {"sim": "m:f"})
    vocab, diags = vocabulary(mission, PluginRegistry([spray]))
    assert [d.message for d in diags] == [
        "action 'Spray' is provided by an installed plugin as Spray(rate_s float64); "
        "the declaration must match it"
    ]
    assert "Spray" in implemented_actions(vocab)
    vocab, diags = vocabulary(mission, PluginRegistry(CAMERA_PLUGINS))
    assert diags == [] and "Spray" not in implemented_actions(vocab)
    # A plugin's ranges bound its arguments.
    assert plugin_argument_problem(vocab, "Gimbal", "pitch_deg", -90.0) == ""
    assert plugin_argument_problem(vocab, "Gimbal", "pitch_deg", 45.0) == (
        "Gimbal's pitch_deg must be within -90..30, got 45"
    )
    assert plugin_argument_problem(vocab, "Land", "x_m", 1e9) == ""  # not a plugin's


@pytest.mark.parametrize(
    ("hal", "expected"),
    [
        ({"adapter": "sim"}, ("sim", "sim")),
        ({"adapter": "fake"}, ("fake", "sim")),
        ({"adapter": "mavlink", "autopilot": "px4"}, ("px4", "mavlink")),
        (
            {"adapter": "mavlink", "sim_vehicle": {"autopilot": "ardupilot"}},
            ("ardupilot", "mavlink"),
        ),
        ({"adapter": "mavlink"}, ("mavlink", "mavlink")),
        ({"adapter": "ground"}, ("ground", "ground")),
    ],
)
def test_each_adapter_has_a_label_and_a_family(
    hal: dict[str, object], expected: tuple[str, str]
) -> None:
    assert adapter_of(hal) == expected


SPRAY = typed("\tSpray(duration_s float64)\n\tTakePhoto()\n", "\tD1.Spray(2)\n\tD1.TakePhoto()")


def _eamos(args: list[str], cwd: Path, site: Path | None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "eamos.cli.main", *args],
        cwd=cwd,
        env=env_with(site) if site is not None else None,
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.mark.parametrize("command", ["compile", "check"])
def test_the_fleet_decides_which_drone_lacks_which_action(tmp_path: Path, command: str) -> None:
    site = install_lab(tmp_path / "site")
    (tmp_path / "m.go").write_text(SPRAY, encoding="utf-8")
    (tmp_path / "px4.toml").write_text(
        '[drones.D1.hal]\nadapter = "mavlink"\nsim_vehicle = { autopilot = "px4" }\n',
        encoding="utf-8",
    )
    (tmp_path / "sim.toml").write_text('[defaults.hal]\nadapter = "sim"\n', encoding="utf-8")
    extra = ["-o", str(tmp_path / "out"), "--no-svg"] if command == "compile" else []
    px4 = _eamos([command, "m.go", "--fleet", "px4.toml", *extra], tmp_path, site)
    assert px4.returncode == 2, px4.stderr
    assert "m.go:10:2: error: D1's adapter (px4) does not implement action 'Spray'" in px4.stderr
    assert "implements it for: sim" in px4.stderr
    assert "TakePhoto" not in px4.stderr  # the camera plugins have a MAVLink implementation
    if command == "compile":
        sim = _eamos([command, "m.go", "--fleet", "sim.toml", *extra], tmp_path, site)
        assert sim.returncode == 0, sim.stderr + sim.stdout
    # Without the lab's package, Spray is no action at all: discovery is what makes it one.
    bare = _eamos([command, "m.go", "--fleet", "sim.toml", *extra], tmp_path, None)
    assert bare.returncode == 2
    assert "no adapter implements action 'Spray' yet" in bare.stderr


def test_eamos_check_flies_a_plugin_action_in_virtual_time(tmp_path: Path) -> None:
    site = install_lab(tmp_path / "site")
    (tmp_path / "m.go").write_text(SPRAY, encoding="utf-8")
    done = _eamos(["check", "m.go"], tmp_path, site)
    assert done.returncode == 0, done.stdout + done.stderr
