"""Settings per drone type: ``[types.NAME.hal]`` in a fleet file (issue 14, battery per type).

Precedence, strongest first: ``[drones.X.hal]`` > ``[types.T.hal]`` (the drone's type,
then the types it embeds) > ``[defaults.hal]`` > the type's built-in battery model.
The pure rules are table-driven; then a battery ``If`` takes Then on one type and Else
on another, in the virtual-time driver and through the pre-flight check.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from eamos.check.explore import check_mission, sim_settings
from eamos.compiler import compile_mission
from eamos.config import ConfigError, FleetConfig
from eamos.config.types import builtin_model, merge_hal, type_lineage
from eamos.hal.sim.settings import BATTERY_MODELS, BatteryModel, SimSettings
from eamos.program.uniform import DRONE_TYPES
from eamos.virtual import run_virtual
from eamos.virtual.vehicles import sim_vehicles

from .refusals import assert_fleet_refused

# (defaults, types, lineage, drone table, the value of drain_airborne_pct_per_min)
PRECEDENCE: list[tuple[dict[str, Any], dict[str, dict[str, Any]], tuple[str, ...], dict, Any]] = [
    ({}, {}, (), {}, None),  # nothing said: the simulator's default (no key written)
    ({"drain_airborne_pct_per_min": 5}, {}, ("Quadcopter",), {}, 5),
    (
        {"drain_airborne_pct_per_min": 5},
        {"Quadcopter": {"drain_airborne_pct_per_min": 6}},
        ("Quadcopter",),
        {},
        6,
    ),
    (
        {"drain_airborne_pct_per_min": 5},
        {"Quadcopter": {"drain_airborne_pct_per_min": 6}},
        ("Quadcopter",),
        {"drain_airborne_pct_per_min": 7},
        7,
    ),
    # Another type's table does not apply.
    ({}, {"DroneType2": {"drain_airborne_pct_per_min": 6}}, ("DroneType1",), {}, None),
    # A custom type falls back to the type it embeds ...
    (
        {},
        {"DroneType1": {"drain_airborne_pct_per_min": 6}},
        ("Inspector", "DroneType1"),
        {},
        6,
    ),
    # ... unless the fleet names it: the nearest type wins.
    (
        {},
        {
            "DroneType1": {"drain_airborne_pct_per_min": 6},
            "Inspector": {"drain_airborne_pct_per_min": 8},
        },
        ("Inspector", "DroneType1"),
        {},
        8,
    ),
    # An unbound fleet (no lineage) uses no type table.
    ({}, {"Quadcopter": {"drain_airborne_pct_per_min": 6}}, (), {}, None),
]


@pytest.mark.parametrize("defaults,types,lineage,drone,expected", PRECEDENCE)
def test_drone_over_type_over_defaults(
    defaults: dict[str, Any],
    types: dict[str, dict[str, Any]],
    lineage: tuple[str, ...],
    drone: dict[str, Any],
    expected: Any,
) -> None:
    merged = merge_hal(defaults, types, lineage, drone)
    assert merged.get("drain_airborne_pct_per_min") == expected
    assert merged["adapter"] == "sim"


def test_types_merge_key_by_key() -> None:
    types = {
        "DroneType1": {"battery_pct": 70, "drain_idle_pct_per_min": 1},
        "Inspector": {"battery_pct": 50},
    }
    merged = merge_hal({"speedup": 5}, types, ("Inspector", "DroneType1"), {})
    assert merged == {
        "speedup": 5,
        "battery_pct": 50,
        "drain_idle_pct_per_min": 1,
        "adapter": "sim",
    }


def test_the_builtin_model_lies_under_the_defaults(monkeypatch: pytest.MonkeyPatch) -> None:
    # A built-in model that differs from the simulator's default is written, under everything.
    models = dict(BATTERY_MODELS)
    models["DroneType3"] = BatteryModel(drain_airborne_pct_per_min=9.0)
    monkeypatch.setattr("eamos.config.types.BATTERY_MODELS", models)
    assert merge_hal({}, {}, ("DroneType3",), {})["drain_airborne_pct_per_min"] == 9.0
    under = merge_hal({"drain_airborne_pct_per_min": 5}, {}, ("DroneType3",), {})
    assert under["drain_airborne_pct_per_min"] == 5
    # Only a simulated drone's table gets it: other adapters do not know the field.
    assert "drain_airborne_pct_per_min" not in merge_hal(
        {"adapter": "fake"}, {}, ("DroneType3",), {}
    )


def test_every_builtin_type_has_a_documented_model() -> None:
    assert set(BATTERY_MODELS) == set(DRONE_TYPES)
    text = (Path(__file__).resolve().parents[2] / "docs" / "safety.md").read_text()
    for name, model in BATTERY_MODELS.items():
        assert f"| {name} | {model.drain_airborne_pct_per_min:g} |" in text, name
    default = SimSettings()
    assert BatteryModel() == BatteryModel(
        default.battery_pct,
        default.drain_airborne_pct_per_min,
        default.drain_per_mps_pct_per_min,
        default.drain_climb_per_mps_pct_per_min,
        default.drain_idle_pct_per_min,
    )


@pytest.mark.parametrize(
    "drone_type,declared,lineage",
    [
        ("Quadcopter", {}, ("Quadcopter",)),
        ("", {}, ()),
        ("Inspector", {"Inspector": ["Quadcopter"]}, ("Inspector", "Quadcopter")),
        (
            "Survey",
            {"Survey": ["Inspector", "DroneType2"], "Inspector": ["DroneType1"]},
            ("Survey", "Inspector", "DroneType1", "DroneType2"),
        ),
        ("A", {"A": ["B"], "B": ["A"]}, ("A", "B")),  # a cycle ends (the compiler refuses it)
    ],
)
def test_type_lineage_is_depth_first(
    drone_type: str, declared: dict[str, list[str]], lineage: tuple[str, ...]
) -> None:
    assert type_lineage(drone_type, declared) == lineage


def test_builtin_model_of_a_custom_type_is_its_embedded_types() -> None:
    assert builtin_model(("Inspector", "DroneType2")) is BATTERY_MODELS["DroneType2"]
    assert builtin_model(("Inspector",)) is BATTERY_MODELS["Quadcopter"]


BAD_TYPES = [
    ("[types]\nQuadcopter = 3\n", "types.Quadcopter", "must be a table"),
    (
        "[types.Quadcopter]\nbattery = {}\n",
        "types.Quadcopter.battery",
        "only [types.Quadcopter.hal]",
    ),
    ("[types.Quadcopter]\nhal = 3\n", "types.Quadcopter.hal", "must be a table"),
    (
        "[types.Quadcopter.hal]\ndrain_airbrone_pct_per_min = 3\n",
        "types.Quadcopter.hal.drain_airbrone_pct_per_min",
        "did you mean 'drain_airborne_pct_per_min'",
    ),
    (
        "[types.DroneType1.hal]\ndrain_idle_pct_per_min = -1\n",
        "types.DroneType1.hal.drain_idle_pct_per_min",
        ">= 0",
    ),
    ("[types.DroneType1.hal]\nbattery_pct = 120\n", "types.DroneType1.hal.battery_pct", "<= 100"),
    (
        '[types.DroneType1.hal]\nbattery_pct = "full"\n',
        "types.DroneType1.hal.battery_pct",
        "number",
    ),
    ('[types.DroneType1.hal]\nadapter = "ground"\n', "types.DroneType1.hal.adapter", "ground"),
    ("types = 3\n", "types", "must be a table"),
]


@pytest.mark.parametrize("text,field,words", BAD_TYPES, ids=[r[1] for r in BAD_TYPES])
def test_a_bad_type_table_names_file_and_field(
    tmp_path: Path, text: str, field: str, words: str
) -> None:
    assert_fleet_refused(tmp_path, text, field, words)


def test_a_type_table_for_another_adapter_is_left_to_that_adapter(tmp_path: Path) -> None:
    path = tmp_path / "fleet.toml"
    path.write_text('[types.DroneType1.hal]\nadapter = "mavlink"\nconnection = "udp:x"\n')
    assert FleetConfig.load(path).types == {
        "DroneType1": {"adapter": "mavlink", "connection": "udp:x"}
    }


MISSION = """\
type Inspector interface {
\tDroneType1
}
var D1 Quadcopter
var D2 DroneType1
var D3 Inspector

func SEQ_Main() {
\tPAR_All()
}
func PAR_All() { SEQ_D1(); SEQ_D2(); SEQ_D3() }
func SEQ_D1() { D1.Arm(); D1.Takeoff(2); If(D1.Battery() > 90, SEQ_D1Full, SEQ_D1Low); D1.Land() }
func SEQ_D2() { D2.Arm(); D2.Takeoff(2); If(D2.Battery() > 90, SEQ_D2Full, SEQ_D2Low); D2.Land() }
func SEQ_D3() { D3.Arm(); D3.Takeoff(2); If(D3.Battery() > 90, SEQ_D3Full, SEQ_D3Low); D3.Land() }
func SEQ_D1Full() { D1.FlyByZ(1) }
func SEQ_D1Low() { D1.FlyByZ(-1) }
func SEQ_D2Full() { D2.FlyByZ(1) }
func SEQ_D2Low() { D2.FlyByZ(-1) }
func SEQ_D3Full() { D3.FlyByZ(1) }
func SEQ_D3Low() { D3.FlyByZ(-1) }
"""

FLEET = """\
[defaults.hal]
speedup = 10
[types.DroneType1.hal]
battery_pct = 60          # every DroneType1 starts at 60 %
"""


def _bound(tmp_path: Path, text: str) -> tuple[Any, FleetConfig]:
    compiled = compile_mission(MISSION, str(tmp_path / "types.go"))
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    return compiled, FleetConfig.load(path).for_mission(compiled.programs, compiled.mission.types)


def _branches(run: Any) -> dict[str, str]:
    taken = {}
    for drone in ("D1", "D2", "D3"):
        moves = [args[0] for action, args, _ in run.actions(drone) if action == "FlyByZ"]
        taken[drone] = "Then" if moves == [1.0] else "Else" if moves == [-1.0] else repr(moves)
    return taken


@pytest.mark.parametrize(
    "extra,expected",
    [
        ("", {"D1": "Then", "D2": "Else", "D3": "Else"}),  # Inspector embeds DroneType1
        (
            "[types.Inspector.hal]\nbattery_pct = 100\n",  # the fleet names the custom type
            {"D1": "Then", "D2": "Else", "D3": "Then"},
        ),
        (
            "[drones.D2.hal]\nbattery_pct = 95\n",  # a drone's own table is strongest
            {"D1": "Then", "D2": "Then", "D3": "Else"},
        ),
        (
            # A heavy type drains below 90 % in the seconds of its take-off.
            "[types.Quadcopter.hal]\ndrain_airborne_pct_per_min = 600\n",
            {"D1": "Else", "D2": "Else", "D3": "Else"},
        ),
    ],
)
def test_a_battery_if_takes_its_branch_by_drone_type(
    tmp_path: Path, extra: str, expected: dict[str, str]
) -> None:
    compiled, fleet = _bound(tmp_path, FLEET + extra)
    assert [fleet.drone_type(d) for d in ("D1", "D2", "D3")] == [
        "Quadcopter",
        "DroneType1",
        "Inspector",
    ]
    settings = {d: sim_settings(fleet, d)[0] for d in ("D1", "D2", "D3")}
    run = run_virtual(compiled.programs, sim_vehicles(settings))
    assert not run.timed_out
    assert _branches(run) == expected


def test_the_preflight_check_flies_each_types_model(tmp_path: Path) -> None:
    compiled, fleet = _bound(tmp_path, FLEET + "[safety]\nbattery_reserve_pct = 70\n")
    report = check_mission(compiled, fleet)
    # Only the DroneType1 drones (60 % at start) end below the 70 % reserve.
    low = {d for f in report.findings if f.check == "battery" for d, _ in f.positions}
    assert low == {"D2", "D3"}


@pytest.mark.parametrize(
    "text,words",
    [
        ("[types.DroneTyp1.hal]\nbattery_pct = 50\n", "did you mean 'DroneType1'"),
        ("[types.Inspectr.hal]\nbattery_pct = 50\n", "did you mean 'Inspector'"),
        ("[types.GroundStation.hal]\nbattery_pct = 50\n", "known types: DroneType1"),
    ],
)
def test_a_table_for_an_unknown_type_is_refused(tmp_path: Path, text: str, words: str) -> None:
    with pytest.raises(ConfigError) as info:
        _bound(tmp_path, text)
    message = str(info.value)
    name = text.split("]")[0].split(".")[1]
    assert message.startswith(f"{tmp_path / 'fleet.toml'}: types.{name}: not a drone type"), message
    assert words in message


def test_a_builtin_type_the_mission_does_not_fly_is_accepted(tmp_path: Path) -> None:
    # One fleet file may serve several missions: built-in types are always known.
    _compiled, fleet = _bound(tmp_path, "[types.DroneType3.hal]\nbattery_pct = 50\n")
    assert all(fleet.hal_for(d).get("battery_pct") is None for d in ("D1", "D2", "D3"))


def test_the_example_fleet_file_sends_inspection_if_to_its_else(tmp_path: Path) -> None:
    repo = Path(__file__).resolve().parents[2]
    source = repo / "missions" / "inspection_if.go"
    compiled = compile_mission(source.read_text(encoding="utf-8"), str(source))
    fleet = FleetConfig.load(repo / "configs" / "fleet_types.toml")
    bound = fleet.for_mission(compiled.programs, compiled.mission.types)
    assert bound.hal_for("Drone1")["battery_pct"] == 45
    assert bound.hal_for("Drone2")["battery_pct"] == 100
    settings = {d: sim_settings(bound, d)[0] for d in ("Drone1", "Drone2")}
    run = run_virtual(compiled.programs, sim_vehicles(settings))
    targets = [args for action, args, _ in run.actions("Drone1") if action == "FlyToXYZ"]
    assert (2.0, 0.0, 3.0) in targets and (4.0, 4.0, 3.0) not in targets  # the short one
    unbound = run_virtual(compiled.programs)
    full = [args for action, args, _ in unbound.actions("Drone1") if action == "FlyToXYZ"]
    assert (4.0, 4.0, 3.0) in full
