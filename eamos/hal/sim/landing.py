"""The simulated autopilot's disarm after landing (pure: no thread, no clock read).

Real autopilots disarm by themselves once a flight has ended on the ground: PX4
"Disarmed by landing" ``COM_DISARM_LAND`` seconds (2 by default) after its land
detector says landed, ArduCopter about 2 s after "Land complete"
(``/work/shared/notes``).  The simulated vehicle does the same,
``disarm_after_landing_s`` simulated seconds after a touchdown that ended a
flight (a ``[hal]`` setting, per drone type in a fleet file: docs/configuration.md;
0 turns it off, as ``COM_DISARM_LAND = 0`` does on PX4).

Only a landing counts: a vehicle armed on the ground that never took off stays
armed (the mission must take off or ``Disarm()``), and a take-off before the
delay is up cancels the pending disarm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from eamos.hal.settings import DISARM_AFTER_LANDING_S

__all__ = ["DISARM_AFTER_LANDING_S", "LandingDisarm"]


@dataclass
class LandingDisarm:
    """When the vehicle disarms itself after its last touchdown, counted in simulator steps.

    ``delay_steps`` is None when the vehicle never disarms by itself.  :meth:`update`
    runs after every step with the flags before and after it; :attr:`due_step` is the
    step at whose end the vehicle disarms (None: no disarm pending).
    """

    delay_steps: int | None
    due_step: int | None = None

    @classmethod
    def of(cls, delay_s: float, dt_s: float) -> LandingDisarm:
        """The rule for a delay of ``delay_s`` simulated seconds (0: off) at steps of ``dt_s``."""
        if delay_s <= 0:
            return cls(None)
        # At least one step, and no step short of the delay (float noise aside).
        return cls(max(1, math.ceil(delay_s / dt_s - 1e-9)))

    @property
    def pending(self) -> bool:
        """True while a disarm after landing is due."""
        return self.due_step is not None

    def update(self, step: int, was_landed: bool, landed: bool, armed: bool) -> bool:
        """After step number ``step``: True when the vehicle must disarm now.

        ``was_landed``/``landed``: on the ground before and after the step; ``armed``: now.
        """
        if not armed or not landed:
            self.due_step = None  # disarmed already, or flying (again)
            return False
        if not was_landed and self.delay_steps is not None:
            self.due_step = step + self.delay_steps  # touchdown: the count starts
            return False
        if self.due_step is not None and step >= self.due_step:
            self.due_step = None
            return True
        return False

    def idle_limit(self, step: int) -> int | None:
        """How many steps after ``step`` may be skipped before the disarm (None: no bound)."""
        if self.due_step is None:
            return None
        return max(0, self.due_step - step - 1)


__all__ = ["DISARM_AFTER_LANDING_S", "LandingDisarm"]
