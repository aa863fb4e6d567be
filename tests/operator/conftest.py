"""The SITL fixtures (tests/sitl/conftest.py) for the operator's tests on real autopilots."""

from tests.sitl.conftest import sitl, sitl_fleet

__all__ = ["sitl", "sitl_fleet"]
