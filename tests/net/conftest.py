"""Fixtures for network-layer tests: a ZeroMQ context and bridge factories.

All sockets use loopback TCP with ephemeral ports (port 0) so tests never
collide, and every wait is on a condition with a generous timeout (the test
machine is small and shared), never a sleep.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
import zmq

from .net_helpers import Bridges


@pytest.fixture
def ctx() -> Iterator[zmq.Context[Any]]:
    context: zmq.Context[Any] = zmq.Context()
    yield context
    context.destroy(linger=0)


@pytest.fixture
def bridges(ctx: zmq.Context[Any]) -> Iterator[Bridges]:
    made = Bridges(ctx)
    yield made
    made.close_all()
