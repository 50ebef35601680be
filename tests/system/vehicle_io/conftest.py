"""vehicle_io system tests: a bus on the test's private rendezvous (the harness identity)."""

from __future__ import annotations

import pytest
from seaway.runtime.bus import Bus


@pytest.fixture
def bus(zenoh_env):
    b = Bus.open("vessel1")
    try:
        yield b
    finally:
        b.close()
