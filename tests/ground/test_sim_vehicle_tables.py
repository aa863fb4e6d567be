"""A fleet file's ``sim_vehicle`` table becomes the simulated vehicle's command line."""

from __future__ import annotations

import pytest

from eamos.config import ConfigError
from eamos.ground.vehicles import _vehicle_args


def test_every_key_becomes_its_option() -> None:
    args = _vehicle_args(
        "D1",
        {
            "autopilot": "px4",
            "prearm_delay_s": 2,
            "disarm_after_s": 30,
            "wander_m": 0.3,
            "seed": 7,
            "die_after_s": 12.5,
            "signing_key": "keys/mavlink_signing.key",
            "sysid": 3,
        },
        speedup=5.0,
    )
    assert args[:2] == ["--autopilot", "px4"]
    pairs = dict(zip(args[2::2], args[3::2], strict=True))
    assert pairs == {
        "--speedup": "5.0",
        "--prearm-delay": "2.0",
        "--disarm-after": "30.0",
        "--wander": "0.3",
        "--die-after": "12.5",
        "--seed": "7",
        "--signing-key": "keys/mavlink_signing.key",
        "--sysid": "3",
    }


@pytest.mark.parametrize(
    "table,message",
    [
        ({"autopilot": "px4", "seed": 1.5}, "seed: must be an integer"),
        ({"autopilot": "px4", "wander_m": -1}, "wander_m: must be a number >= 0"),
        ({"autopilot": "px4", "signing_key": ""}, "signing_key: must be the path"),
        ({"autopilot": "px4", "wobble": 1}, "wobble: unknown field"),
    ],
)
def test_bad_values_are_located_errors(table: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        _vehicle_args("D1", table, None)
