"""How long a drone waits at its end for its autopilot's disarm after landing."""

from __future__ import annotations

import pytest

from eamos.config.node import AUTOPILOT_DISARM_WAIT_S, SIM_DISARM_SLACK_S, disarm_wait_s


@pytest.mark.parametrize(
    "hal,expected",
    [
        ({"adapter": "sim"}, 2.0 + SIM_DISARM_SLACK_S),
        ({"adapter": "sim", "speedup": 10}, 0.2 + SIM_DISARM_SLACK_S),
        ({"adapter": "sim", "disarm_after_landing_s": 5, "speedup": 5}, 1.0 + SIM_DISARM_SLACK_S),
        ({"adapter": "sim", "disarm_after_landing_s": 0}, 0.0),  # it never disarms by itself
        ({"adapter": "mavlink", "connection": "tcp:127.0.0.1:5760"}, AUTOPILOT_DISARM_WAIT_S),
        ({"adapter": "mavlink", "speedup": 10}, AUTOPILOT_DISARM_WAIT_S / 10),
        ({"adapter": "fake"}, 0.0),
        ({"adapter": "ground"}, 0.0),
    ],
)
def test_the_wait_follows_the_adapter_and_its_delay(hal: dict, expected: float) -> None:
    assert disarm_wait_s(hal) == pytest.approx(expected)
