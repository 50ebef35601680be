"""The ground station's settings: the operator token and the bounds on what clients may do."""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from seaway.vessel.frames import GeoOrigin

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8321
ENV_TOKEN = "SEAWAY_GROUNDSTATION_TOKEN"


def new_token() -> str:
    """A fresh operator token (URL-safe, 256 bits)."""
    return secrets.token_urlsafe(32)


@dataclass(frozen=True)
class Settings:
    """What ``create_app`` needs besides the bus.

    Times in seconds, sizes in bytes, rates in requests (or frames) per second.
    """

    token: str = field(default_factory=new_token, repr=False)
    """Operator token: ``Authorization: Bearer <token>`` on every request that moves or changes a
    vessel. Generated at start unless configured."""
    max_body_bytes: int = 1 << 20
    """Largest request body accepted (413 beyond)."""
    rate_limit_per_s: float = 5.0
    """Sustained command requests per client (429 beyond)."""
    rate_limit_burst: int = 20
    """Command requests a client may make at once before the sustained rate applies."""
    request_timeout_s: float = 10.0
    """How long a bus request waits for its reply (504 after)."""
    stream_rate_hz: float = 20.0
    """Most frames per second a stream client gets."""
    max_stream_clients: int = 256
    stale_after_s: float = 2.0
    """A message older than this is shown as stale."""
    max_waypoints: int = 1000
    default_origin: GeoOrigin | None = None
    """NED origin for exporting metre waypoints when a vessel has published none (the run's)."""
    scenario_dir: Path | None = None
    """Where scenarios named in a request are read (None: the checkout's deploy/scenarios)."""
    clock: Callable[[], float] = time.monotonic
    """Monotonic clock [s] for ages and the rate limit (tests pass their own)."""

    def __post_init__(self) -> None:
        if len(self.token) < 16:
            raise ValueError("the operator token must be at least 16 characters")
