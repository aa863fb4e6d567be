"""Flying missions on real SITL vehicles through ``eamos run``, and checking how they ended.

:class:`SitlFleet` starts the vehicles (one fresh folder and instance each) and writes the
fleet file with their connection strings; :func:`fly` runs ``eamos run MISSION --fleet
FLEET`` as a user does (a subprocess); :func:`assert_safe_end` checks what every run
here must leave behind: each vehicle landed and disarmed, as the vehicle itself says
afterwards and as the summary says, every parameter the adapter changed back to the
value it found, and no ArduCopter that hit the ground ("SIM Hit ground" in its console).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tests.support.runs import run_mission

from .sitl_vehicles import (
    Autopilot,
    SitlVehicle,
    inspect_vehicle,
    param_save_failures,
    start_vehicle,
)

#: A camera and a mount on ArduCopter (issue 27): a servo camera (trigger on servo 11)
#: and a servo mount (pitch on servo 9, yaw on servo 10).  They exist after a reboot.
ARDUPILOT_CAMERA = {
    "CAM1_TYPE": 1.0,
    "MNT1_TYPE": 1.0,
    "SERVO9_FUNCTION": 7.0,  # mount pitch (tilt)
    "SERVO10_FUNCTION": 6.0,  # mount yaw (pan)
    "SERVO11_FUNCTION": 10.0,  # camera trigger
}
#: The speed-up each autopilot flies at in the tier: PX4 SIH at 10 takes a whole core
#: (lockstep) and its estimate wanders more on a loaded machine; ArduCopter is light.
SPEEDUP = {"arducopter": 10.0, "px4": 5.0}
#: Generous for a loaded 2-core machine (vehicle seconds; the adapter scales them).
#: Generous for a loaded 2-core CI machine: a SITL starved of CPU for a few seconds is slow,
#: not dead (a killed vehicle is still found lost, 10 s later).
HAL_TIMEOUTS = {
    "connect_timeout_s": 60,
    "armable_timeout_s": 120,
    "action_timeout_s": 120,
    "heartbeat_timeout_s": 10,
}


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    return repr(value)


@dataclass
class SitlFleet:
    """Real vehicles for one test, and the fleet file that names them."""

    speedup: float
    vehicles: dict[str, SitlVehicle]
    sim_drones: tuple[str, ...] = ()
    hal: dict[str, dict[str, Any]] = field(default_factory=dict)

    @classmethod
    def start(
        cls,
        sitl: Path,
        folder: Path,
        drones: dict[str, Autopilot | str],
        speedup: float,
        camera: tuple[str, ...] = (),
        hal: dict[str, dict[str, Any]] | None = None,
    ) -> SitlFleet:
        """Start a vehicle per MAVLink drone (``"arducopter"``/``"px4"``); ``"sim"`` drones
        fly the built-in simulator; ``camera``: drones configured with a camera and mount."""
        fleet = cls(speedup, {}, tuple(n for n, a in drones.items() if a == "sim"), hal or {})
        try:
            for name, autopilot in drones.items():
                if autopilot == "sim":
                    continue
                assert autopilot in ("arducopter", "px4"), autopilot
                params = ARDUPILOT_CAMERA if name in camera and autopilot == "arducopter" else None
                fleet.vehicles[name] = start_vehicle(
                    sitl,
                    autopilot,  # type: ignore[arg-type]
                    folder / f"sitl-{name}",
                    speedup,
                    params,
                )
        except BaseException:
            fleet.stop()
            raise
        return fleet

    def stop(self) -> None:
        """Kill every vehicle (by its pid) and free its instance."""
        for vehicle in self.vehicles.values():
            vehicle.stop()

    def write(self, path: Path) -> Path:
        """The fleet file: each vehicle's connection, the speed-up, generous timeouts."""
        lines = ['[defaults.hal]\nadapter = "sim"\n']
        for name, vehicle in self.vehicles.items():
            settings: dict[str, Any] = {
                "adapter": "mavlink",
                "connection": vehicle.connection,
                "speedup": self.speedup,
                **HAL_TIMEOUTS,
                **self.hal.get(name, {}),
            }
            body = "".join(f"{k} = {_toml(v)}\n" for k, v in settings.items())
            lines.append(f"[drones.{name}.hal]\n{body}")
        for name in self.sim_drones:
            lines.append(f'[drones.{name}.hal]\nadapter = "sim"\n')
        path.write_text("\n".join(lines))
        return path


@dataclass
class Flown:
    """One ``eamos run`` of a mission on a :class:`SitlFleet`."""

    returncode: int
    output: str
    summary: dict[str, Any]
    run_dir: Path
    wall_s: float

    def report(self, drone: str) -> dict[str, Any]:
        """The drone's report in the summary."""
        report: dict[str, Any] = self.summary["drones"][drone]
        return report

    def results(self, drone: str) -> list[tuple[str, list[Any], str]]:
        """(action, args, result) of each action the drone ran, in order."""
        return [(a["action"], a["args"], a["result"]) for a in self.report(drone)["actions"]]

    def events(self, drone: str, name: str | None = None) -> list[dict[str, Any]]:
        """The drone's adapter log (``name``: only those events)."""
        path = self.run_dir / "logs" / drone / "adapter.log"
        lines = path.read_text().splitlines()
        events = [json.loads(line) for line in lines if line.strip()]
        return [e for e in events if name is None or e["event"] == name]

    def action_ends(self, drone: str) -> list[dict[str, Any]]:
        """``adapter.action.end`` events: where the vehicle was when each action ended."""
        return self.events(drone, "adapter.action.end")


def fly(tmp_path: Path, fleet: SitlFleet, mission: str | Path, timeout_s: float = 300) -> Flown:
    """``eamos run MISSION --fleet FLEET`` at the fleet's speed-up, to its end."""
    import time

    if isinstance(mission, str):
        path = tmp_path / "mission.go"
        path.write_text(mission)
        mission = path
    fleet_file = fleet.write(tmp_path / "fleet.toml")
    began = time.monotonic()
    proc, summary = run_mission(
        tmp_path,
        mission,
        "--fleet",
        str(fleet_file),
        speedup=fleet.speedup,
        timeout_s=timeout_s,
        process_timeout_s=timeout_s + 120,
    )
    wall = time.monotonic() - began
    output = proc.stdout + proc.stderr
    assert summary, f"no summary written:\n{output}"
    return Flown(proc.returncode, output, summary, Path(summary["run_dir"]), wall)


def changed_params(flown: Flown, drone: str) -> dict[str, float]:
    """Every parameter the adapter set on ``drone``'s vehicle, with the value it found."""
    found: dict[str, float] = {}
    for event in flown.events(drone, "adapter.param.set"):
        found.setdefault(event["name"], float(event["before"]))
    return found


def assert_safe_end(flown: Flown, fleet: SitlFleet) -> None:
    """Every vehicle landed and disarmed (its own word and the summary's), its parameters
    restored, no ArduCopter hit the ground, nothing stranded."""
    for drone in fleet.vehicles:
        final = flown.report(drone)["final"]
        assert final["landed"] and not final["armed"], (drone, final)
    assert_vehicles_safe(flown, fleet)


def assert_vehicles_safe(flown: Flown, fleet: SitlFleet) -> None:
    """What the vehicles say after the run: landed and disarmed, their parameters
    restored; no ArduCopter hit the ground; nothing stranded."""
    for drone, vehicle in fleet.vehicles.items():
        params = changed_params(flown, drone)
        state = inspect_vehicle(vehicle, params)
        assert not state.armed, f"{drone}: the vehicle is still armed"
        assert state.landed_state == 1, f"{drone}: landed_state {state.landed_state}"
        for name, before in params.items():
            assert math.isclose(state.params[name], before, rel_tol=1e-4, abs_tol=1e-4), (
                f"{drone}: {name} is {state.params[name]}, was {before} before the run"
            )
        assert not flown.events(drone, "adapter.stranded"), flown.events(drone, "adapter.stranded")
        failures = param_save_failures(vehicle.autopilot, vehicle.folder)
        assert not failures, (drone, failures)
        if vehicle.autopilot == "arducopter":
            hits = [line for line in vehicle.console.splitlines() if "Hit ground" in line]
            assert not hits, f"{drone}: {hits}"


def positions_during(flown: Flown, drone: str, action: str) -> list[dict[str, Any]]:
    """The ``adapter.position`` events the adapter logged while ``action`` ran on ``drone``."""
    positions: list[dict[str, Any]] = []
    running = False
    for event in flown.events(drone):
        if event["event"] == "adapter.action.start" and event["action"] == action:
            running = True
        elif event["event"] == "adapter.action.end" and event["action"] == action:
            running = False
        elif running and event["event"] == "adapter.position":
            positions.append(event)
    return positions


def heights_during(flown: Flown, drone: str, action: str) -> list[float]:
    """Heights (mission z) the adapter logged while ``action`` ran on ``drone``."""
    return [float(event["z_m"]) for event in positions_during(flown, drone, action)]
