"""The simulator's telemetry sampling and position log (pure: no thread, no clock read).

Split from :mod:`eamos.hal.sim.core`: how the simulated vehicle's state becomes
telemetry samples and ``adapter.position`` lines.
"""

from __future__ import annotations

import functools
import itertools
import math
import operator
from collections.abc import Callable
from typing import TYPE_CHECKING

from eamos.hal.api import POSITION_LOG_HZ, Telemetry
from eamos.hal.kinematics import GeoFrame, VehicleState
from eamos.hal.sim.settings import SimSettings

if TYPE_CHECKING:
    from eamos.logs import EventLog

#: Simulated seconds between position log lines.
POSITION_LOG_PERIOD_S = 1.0 / POSITION_LOG_HZ
#: Absorbs float error in summed step times when comparing simulated times.
EPS_S = 1e-9


class TelemetrySampler:
    """Telemetry sampling: quantized samples at ``telemetry_hz``, sent only on change.

    Also writes the ``adapter.position`` log line at ``POSITION_LOG_HZ`` of
    simulated time while the position or the armed/landed flags change.
    """

    def __init__(
        self, drone: str, settings: SimSettings, log: EventLog, clock: Callable[[], float]
    ) -> None:
        self._drone = drone
        self._period_s = 1.0 / settings.telemetry_hz
        self._frame: GeoFrame = settings.frame
        self._log = log
        self._clock = clock
        self._next_sample_s = 0.0
        self._last_sample_key: tuple[float | bool, ...] | None = None
        self._next_position_log_s = 0.0
        self._last_position_key: tuple[float | bool, ...] | None = None
        # The raw state the last sample and the last position line showed
        # (for shows(); None until the first of each).
        self._sampled_raw: tuple[float | bool, ...] | None = None
        self._sampled_battery: float | None = None
        self._logged_raw: tuple[float | bool, ...] | None = None

    def first(self, st: VehicleState) -> Telemetry:
        """The sample sent at start; the next one is due one period later."""
        sample = self.sample(st)
        self._last_sample_key = sample.state()
        self._sampled_raw = (st.x_m, st.y_m, st.z_m, st.armed, st.landed)
        self._sampled_battery = sample.battery_pct
        self._next_sample_s = self._period_s
        return sample

    def sample(self, st: VehicleState) -> Telemetry:
        """``st`` as a telemetry sample, quantized to 1 cm / 1e-7 degree / 0.1 %."""
        lat, lon, alt = self._frame.to_lla(st.x_m, st.y_m, st.z_m)
        return Telemetry(
            drone=self._drone,
            time_s=self._clock(),
            x_m=round(st.x_m, 2) + 0.0,  # + 0.0 turns -0.0 into 0.0
            y_m=round(st.y_m, 2) + 0.0,
            z_m=round(st.z_m, 2) + 0.0,
            lat_deg=round(lat, 7),
            lon_deg=round(lon, 7),
            alt_m=round(alt, 2) + 0.0,
            battery_pct=round(st.battery_pct, 1),
            armed=st.armed,
            landed=st.landed,
        )

    def shows(self, raw: tuple[float | bool, ...]) -> bool:
        """True when the last sample and position line show ``raw``, ``(x_m, y_m, z_m,
        armed, landed)``: then the coming steps of a vehicle at rest emit nothing
        until that (or the shown battery) changes.  Compared on the raw state (exact
        at rest): costs no sample."""
        return raw == self._sampled_raw == self._logged_raw

    def shows_battery(self, shown_battery_pct: float) -> bool:
        """True when the last sample shows this battery value (0.1 %)."""
        return shown_battery_pct == self._sampled_battery

    def first_sample_step(self, step: int, dt_s: float) -> int:
        """The first step number from ``step`` on at which a sample is due, the steps
        before it skipped (:meth:`catch_up`); step ``k`` ends at ``k * dt_s``."""
        due, _ = _passed(self._next_sample_s, self._period_s, (step - 1) * dt_s + EPS_S)
        return self.first_step_at(due, step, dt_s)

    @staticmethod
    def first_step_at(due_s: float, step: int, dt_s: float) -> int:
        """The first step number from ``step`` on at which a sample due at ``due_s`` is taken."""
        k = max(step, math.ceil((due_s - EPS_S) / dt_s))
        while k > step and (k - 1) * dt_s >= due_s - EPS_S:
            k -= 1  # float rounding put it one late
        while k * dt_s < due_s - EPS_S:
            k += 1  # ... or one early
        return k

    def catch_up(self, t_s: float) -> float | None:
        """Move the sampling schedule to ``t_s`` as the skipped steps would have.

        Returns when the last sample due in them was due (None: none was).
        """
        self._next_sample_s, fired = _passed(self._next_sample_s, self._period_s, t_s + EPS_S)
        while t_s >= self._next_position_log_s - EPS_S:
            self._next_position_log_s += POSITION_LOG_PERIOD_S
        return fired

    def resample(self, st: VehicleState) -> Telemetry | None:
        """The sample a due step showing ``st`` sends (None: it would show nothing new),
        its state then taken as shown (a skipped step's sample, sent late)."""
        sample = self.sample(st)
        key = sample.state()
        self._sampled_raw = (st.x_m, st.y_m, st.z_m, st.armed, st.landed)
        self._sampled_battery = sample.battery_pct
        if key == self._last_sample_key:
            return None
        self._last_sample_key = key
        return sample

    def observe(self, t_s: float, st: VehicleState, samples: list[Telemetry]) -> None:
        """After a step at ``t_s``: append a sample if one is due and differs."""
        if t_s >= self._next_sample_s - EPS_S:
            while self._next_sample_s <= t_s + EPS_S:
                self._next_sample_s += self._period_s
            raw = (st.x_m, st.y_m, st.z_m, st.armed, st.landed)
            # Unchanged since the last sample (a vehicle at rest): the same sample, not sent.
            if raw != self._sampled_raw or round(st.battery_pct, 1) != self._sampled_battery:
                sample = self.sample(st)
                key = sample.state()
                if key != self._last_sample_key:
                    self._last_sample_key = key
                    samples.append(sample)
                self._sampled_raw = raw
                self._sampled_battery = sample.battery_pct
        if t_s >= self._next_position_log_s - EPS_S:
            self._next_position_log_s += POSITION_LOG_PERIOD_S
            raw = (st.x_m, st.y_m, st.z_m, st.armed, st.landed)
            if raw == self._logged_raw:
                return  # unchanged: no line
            self._logged_raw = raw
            key = (round(st.x_m, 2), round(st.y_m, 2), round(st.z_m, 2), st.armed, st.landed)
            if key != self._last_position_key:
                self._last_position_key = key
                self._log.info(
                    "adapter.position",
                    x_m=key[0],
                    y_m=key[1],
                    z_m=key[2],
                    speed_mps=round(st.speed_mps, 2),
                    armed=st.armed,
                    landed=st.landed,
                    battery_pct=round(st.battery_pct, 1),
                    t_sim=round(t_s, 3),
                )


class ReadRate:
    """Which samples of a vehicle go out when they are read at most every ``period_s``
    (pure: wall time passed in; :meth:`eamos.hal.sim.adapter.SimAdapter.read_at_most`).

    ``period_s`` None: every sample, as it comes.  Otherwise a moving vehicle sends its
    latest sample once a period and holds the newer ones, as the link would coalesce
    them anyway (:class:`eamos.net.liveness.TelemetryOut`, the same rule): at 10 Hz of
    simulated time and x10, a flying drone made a hundred samples a wall second for
    two that left.  A sample that arms, disarms, lands or takes off goes at once, and
    so does the latest when an action ends or the vehicle comes to rest.
    """

    def __init__(self) -> None:
        self.period_s: float | None = None
        self.sent_at = 0.0  # wall time the last sample went out
        self._held: Telemetry | None = None
        self._flags: tuple[bool, bool] | None = None

    def pass_on(self, samples: list[Telemetry], now: float, news: bool) -> list[Telemetry]:
        """What goes out at ``now`` of ``samples`` (a pace's, oldest first) and of the one
        held before; ``news``: an action ended, or the vehicle rests from now on."""
        if self._held is not None:
            samples = [self._held, *samples]
            self._held = None
        if not samples:
            return samples
        if self.period_s is not None:
            latest = samples[-1]
            news = news or (latest.armed, latest.landed) != self._flags
            if not (news or now >= self.sent_at + self.period_s):
                self._held = latest
                return []
            samples = [latest]
        self.sent_at = now
        self._flags = (samples[-1].armed, samples[-1].landed)
        return samples


def _passed(due: float, period: float, bound: float) -> tuple[float, float | None]:
    """``due`` plus ``period`` until it exceeds ``bound``: the loop ``while due <= bound:
    due += period``, its sums the same (the additions before the last few in a C loop);
    and the last value it passed (None: ``due`` was beyond ``bound`` already)."""
    last = None
    sure = int((bound - due) / period) - 2  # additions that surely stay <= bound
    if sure > 0:
        ahead = functools.reduce(operator.add, itertools.repeat(period, sure), due)
        if ahead <= bound:
            due = ahead  # (an addition surely follows below: it sets ``last``)
    while due <= bound:
        last = due
        due += period
    return due, last


__all__ = ["EPS_S", "POSITION_LOG_PERIOD_S", "ReadRate", "TelemetrySampler"]
