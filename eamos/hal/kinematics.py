"""A pure kinematic quadcopter model and the local-to-global frame conversion.

The model has no threads and no clock: callers advance it with
:meth:`Quadcopter.step`.  It is shared by :class:`eamos.hal.sim.adapter.SimAdapter`
and by the simulated MAVLink vehicle, so both fly the same way.

Motion model.  Horizontal (X/Y, as one 2-D vector) and vertical (Z) motion are
two independent channels, like a multicopter position controller: each one
accelerates towards its target at most ``accel_mps2``, cruises at most at its
speed limit (climb and descent differ) and brakes along ``v = sqrt(2 a d)``,
which gives the classic trapezoidal speed profile.  The commanded speed is
also capped to ``d / dt`` so a step never jumps past the target; with
semi-implicit Euler integration the vehicle then lands exactly on the target
instead of overshooting.

Frame: X north, Y east, Z up, metres from home; the ground is ``z == 0``.
"""

from __future__ import annotations

import functools
import itertools
import math
import operator
from dataclasses import dataclass

#: Mean equatorial Earth radius used by the flat-earth approximation (WGS84 a).
EARTH_RADIUS_M = 6_378_137.0

#: Distances and speeds below these are treated as "arrived" and "at rest".
_SNAP_DISTANCE_M = 1e-4
_REST_SPEED_MPS = 1e-6


@dataclass(frozen=True)
class Limits:
    """Physical limits of the simulated quadcopter (defaults: a small survey drone)."""

    horizontal_speed_mps: float = 2.0
    climb_speed_mps: float = 1.0
    descent_speed_mps: float = 0.7
    accel_mps2: float = 2.0
    # The battery model (see :meth:`Quadcopter.drain_pct_per_min`): hovering
    # costs the most, speed and climbing add to it; a vehicle on the ground
    # draws only its electronics.  Defaults: about 25 minutes of hover.
    drain_airborne_pct_per_min: float = 4.0
    drain_per_mps_pct_per_min: float = 0.5
    drain_climb_per_mps_pct_per_min: float = 2.0
    drain_idle_pct_per_min: float = 0.1

    def __post_init__(self) -> None:
        for name in ("horizontal_speed_mps", "climb_speed_mps", "descent_speed_mps", "accel_mps2"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0")
        for name in (
            "drain_airborne_pct_per_min",
            "drain_per_mps_pct_per_min",
            "drain_climb_per_mps_pct_per_min",
            "drain_idle_pct_per_min",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0")


@dataclass(frozen=True)
class VehicleState:
    """A snapshot of the model (positions in metres, velocities in m/s)."""

    x_m: float
    y_m: float
    z_m: float
    vx_mps: float
    vy_mps: float
    vz_mps: float
    armed: bool
    landed: bool
    battery_pct: float

    @property
    def speed_mps(self) -> float:
        """The 3-D speed."""
        return math.sqrt(self.vx_mps**2 + self.vy_mps**2 + self.vz_mps**2)

    @property
    def horizontal_speed_mps(self) -> float:
        """The speed over ground."""
        return math.hypot(self.vx_mps, self.vy_mps)


def _channel(
    pos: tuple[float, ...],
    vel: tuple[float, ...],
    target: tuple[float, ...],
    vmax: float,
    accel: float,
    dt: float,
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Advance one motion channel (1-D or 2-D) by ``dt`` towards ``target``."""
    delta = [t - p for t, p in zip(target, pos, strict=True)]
    dist = math.sqrt(sum(d * d for d in delta))
    speed = math.sqrt(sum(v * v for v in vel))
    if dist <= _SNAP_DISTANCE_M and speed <= accel * dt:
        # Close enough and slow enough to stop within this step: arrive exactly.
        return tuple(target), tuple(0.0 for _ in vel)
    if dist > 0.0:
        # The braking curve makes the deceleration phase of the trapezoid.  It
        # is the discrete-time form of v = sqrt(2 a d): the fastest speed from
        # which braking by a*dt per step stops within d, so the vehicle never
        # overshoots; d / dt keeps the last step from jumping past the target.
        step_dv = accel * dt
        braking = step_dv * (math.sqrt(0.25 + 2.0 * dist / (step_dv * dt)) - 0.5)
        desired = min(vmax, braking, dist / dt)
        v_des = [d / dist * desired for d in delta]
    else:
        v_des = [0.0 for _ in vel]
    dv = [vd - v for vd, v in zip(v_des, vel, strict=True)]
    dv_norm = math.sqrt(sum(x * x for x in dv))
    max_dv = accel * dt
    if dv_norm > max_dv:
        dv = [x * max_dv / dv_norm for x in dv]
    new_vel = tuple(v + x for v, x in zip(vel, dv, strict=True))
    # Semi-implicit Euler: position moves with the new velocity.
    new_pos = tuple(p + v * dt for p, v in zip(pos, new_vel, strict=True))
    return new_pos, new_vel


class Quadcopter:
    """A kinematic quadcopter: position, velocity, armed/landed flags and battery.

    Commands (:meth:`arm`, :meth:`set_target`, :meth:`hold`, :meth:`land`) only
    change the setpoint; :meth:`step` moves the vehicle.  The model refuses only
    what is physically meaningless (disarming in the air); mission rules such as
    "takeoff needs armed" belong to the adapter.
    """

    def __init__(
        self,
        limits: Limits | None = None,
        *,
        x_m: float = 0.0,
        y_m: float = 0.0,
        battery_pct: float = 100.0,
    ) -> None:
        self.limits = limits or Limits()
        self._x, self._y, self._z = float(x_m), float(y_m), 0.0
        self._vx = self._vy = self._vz = 0.0
        self._armed = False
        self._landed = True
        self._battery = min(100.0, max(0.0, float(battery_pct)))
        self._target: tuple[float, float, float] | None = None

    @classmethod
    def at(cls, state: VehicleState, limits: Limits | None = None) -> Quadcopter:
        """A model that goes on from ``state`` (a vehicle's position, velocity, armed,
        landed, battery as a mission snapshot recorded them); in the air it brakes to
        hold where it is, as a vehicle told nothing new."""
        model = cls(limits, x_m=state.x_m, y_m=state.y_m, battery_pct=state.battery_pct)
        model._z = max(0.0, float(state.z_m))
        model._armed = bool(state.armed)
        model._landed = bool(state.landed) or model._z <= 0.0
        if not model._landed:
            model._vx, model._vy, model._vz = state.vx_mps, state.vy_mps, state.vz_mps
        model.hold()
        return model

    # -- reading -----------------------------------------------------------

    @property
    def state(self) -> VehicleState:
        """A frozen snapshot of the current state."""
        return VehicleState(
            self._x,
            self._y,
            self._z,
            self._vx,
            self._vy,
            self._vz,
            self._armed,
            self._landed,
            self._battery,
        )

    @property
    def position(self) -> tuple[float, float, float]:
        """The current (x, y, z) in metres from home."""
        return (self._x, self._y, self._z)

    @property
    def target(self) -> tuple[float, float, float] | None:
        """The current setpoint, or None when there is none (on the ground)."""
        return self._target

    @property
    def armed(self) -> bool:
        """True while the motors are armed."""
        return self._armed

    @property
    def landed(self) -> bool:
        """True while the vehicle stands on the ground."""
        return self._landed

    @property
    def battery_pct(self) -> float:
        """Remaining battery, 0 to 100."""
        return self._battery

    def distance_to(self, point: tuple[float, float, float]) -> float:
        """3-D distance from the vehicle to ``point``."""
        return math.dist(self.position, point)

    def at_target(self, tolerance_m: float, settle_speed_mps: float) -> bool:
        """True when there is a target, it is within ``tolerance_m`` and the vehicle is slow."""
        return (
            self._target is not None
            and self.distance_to(self._target) <= tolerance_m
            and self.state.speed_mps <= settle_speed_mps
        )

    # -- commanding --------------------------------------------------------

    def arm(self) -> None:
        """Arm the motors (the adapter decides whether the vehicle is armable)."""
        self._armed = True

    def disarm(self) -> None:
        """Disarm the motors; raises ValueError in the air, where that would be a crash."""
        if not self._landed:
            raise ValueError("cannot disarm in the air")
        self._armed = False
        self._target = None

    def set_target(self, x_m: float, y_m: float, z_m: float) -> None:
        """Fly towards (x, y, z); z is clamped to the ground."""
        self._target = (float(x_m), float(y_m), max(0.0, float(z_m)))

    def hold(self) -> None:
        """Hold the current position (on the ground: keep standing)."""
        self._target = None if self._landed else self.position

    def land(self) -> None:
        """Descend vertically at the current X/Y until on the ground (there: stay)."""
        self._target = None if self._landed else (self._x, self._y, 0.0)

    # -- simulating --------------------------------------------------------

    def drain_pct_per_min(self) -> float:
        """The battery's drain now: idle on the ground; in the air hover plus load.

        Load is the 3-D speed (``drain_per_mps_pct_per_min`` per m/s) and the
        climb rate (``drain_climb_per_mps_pct_per_min`` per m/s upwards), so a
        long, fast or climbing flight empties the battery sooner than a hover.
        """
        lim = self.limits
        if self._landed:
            return lim.drain_idle_pct_per_min
        speed = math.sqrt(self._vx**2 + self._vy**2 + self._vz**2)
        return (
            lim.drain_airborne_pct_per_min
            + lim.drain_per_mps_pct_per_min * speed
            + lim.drain_climb_per_mps_pct_per_min * max(0.0, self._vz)
        )

    @property
    def at_rest(self) -> bool:
        """True when :meth:`step` can change nothing but the battery.

        On the ground without a climb setpoint, or hovering exactly on the
        setpoint with zero velocity (the model then stays put bit for bit);
        lets a virtual-time driver skip steps in which nothing happens.
        """
        if self._landed:
            target = self._target
            return not (self._armed and target is not None and target[2] > 0.0)
        return (
            self._target == (self._x, self._y, self._z)
            and self._vx == 0.0
            and self._vy == 0.0
            and self._vz == 0.0
        )

    def rest(self, dt_s: float, steps: int) -> None:
        """``steps`` steps of ``dt_s`` while :attr:`at_rest`: only the battery drains.

        Drains step by step, exactly as many :meth:`step` calls would.
        """
        if not self.at_rest:
            raise ValueError("rest() while moving")
        per_step = self.drain_pct_per_min() * dt_s / 60.0
        # The drain subtracted once per step, in order (a C loop): once below zero
        # it stays below, so clamping the sum gives what clamping every step gives.
        drained = functools.reduce(operator.sub, itertools.repeat(per_step, steps), self._battery)
        self._battery = max(0.0, drained)

    def step(self, dt_s: float) -> None:
        """Advance the model by ``dt_s`` seconds."""
        if dt_s <= 0:
            raise ValueError("dt_s must be > 0")
        lim = self.limits
        at_rest = self.at_rest  # before the drain: it reads the state the step starts from
        self._battery = max(0.0, self._battery - self.drain_pct_per_min() * dt_s / 60.0)
        if at_rest and not self._landed:
            return  # hovering on the setpoint: the steps below leave it bit for bit

        target = self._target
        if self._landed:
            # A vehicle on the ground only moves when armed and told to climb.
            if not (self._armed and target is not None and target[2] > 0.0):
                self._vx = self._vy = self._vz = 0.0
                return
            self._landed = False

        if target is None:
            # Airborne without a setpoint: brake to a hover where we are.
            target = self.position
            self._target = target

        vx0, vy0 = self._vx, self._vy
        (self._x, self._y), (self._vx, self._vy) = _channel(
            (self._x, self._y),
            (self._vx, self._vy),
            target[:2],
            lim.horizontal_speed_mps,
            lim.accel_mps2,
            dt_s,
        )
        vmax_z = lim.climb_speed_mps if target[2] >= self._z else lim.descent_speed_mps
        (self._z,), (self._vz,) = _channel(
            (self._z,), (self._vz,), (target[2],), vmax_z, lim.accel_mps2, dt_s
        )

        if self._z <= 0.0 and target[2] <= 0.0:
            # Touchdown: the ground stops the vehicle.
            self._z = 0.0
            self._vx = self._vy = self._vz = 0.0
            self._landed = True
            self._target = None
        elif self._z < 0.0:
            self._z, self._vz = 0.0, 0.0
        if (
            abs(self._vx) < _REST_SPEED_MPS
            and abs(self._vy) < _REST_SPEED_MPS
            and math.hypot(vx0, vy0) <= lim.accel_mps2 * dt_s
        ):
            # Snap a crawl to rest, unless that change of speed would itself
            # exceed the acceleration limit (it then rests one step later).
            self._vx = self._vy = 0.0


@dataclass(frozen=True)
class GeoFrame:
    """Converts the local frame (X north, Y east, Z up from home) to WGS84 and back.

    A flat-earth (equirectangular) approximation around home: accurate to
    centimetres over the few hundred metres a mission spans.  Altitudes in the
    uniform API are metres *above home* (``Alt`` property, ``FlyToLLA``), so
    :meth:`to_lla` and :meth:`from_lla` use that; ``home_alt_m`` is the
    altitude of home above mean sea level, for vehicles that need AMSL
    (see :meth:`amsl_m`).
    """

    home_lat_deg: float = 46.6103  # Klagenfurt, as in the paper's experiments
    home_lon_deg: float = 14.2640
    home_alt_m: float = 0.0

    def to_lla(self, x_m: float, y_m: float, z_m: float) -> tuple[float, float, float]:
        """Local (x, y, z) -> (lat_deg, lon_deg, alt_m above home)."""
        lat = self.home_lat_deg + math.degrees(x_m / EARTH_RADIUS_M)
        lon = self.home_lon_deg + math.degrees(
            y_m / (EARTH_RADIUS_M * math.cos(math.radians(self.home_lat_deg)))
        )
        return lat, lon, z_m

    def from_lla(self, lat_deg: float, lon_deg: float, alt_m: float) -> tuple[float, float, float]:
        """(lat_deg, lon_deg, alt_m above home) -> local (x, y, z)."""
        x = math.radians(lat_deg - self.home_lat_deg) * EARTH_RADIUS_M
        y = (
            math.radians(lon_deg - self.home_lon_deg)
            * EARTH_RADIUS_M
            * math.cos(math.radians(self.home_lat_deg))
        )
        return x, y, alt_m

    def amsl_m(self, z_m: float) -> float:
        """Altitude above mean sea level of a point ``z_m`` above home."""
        return self.home_alt_m + z_m
