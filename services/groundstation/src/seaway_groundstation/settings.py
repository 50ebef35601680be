"""The ground station's settings: the operator token and the bounds on what clients may do."""

from __future__ import annotations

import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from seaway.runtime.run import CONTROL_PERIOD_S, DEFAULT_VESSEL_FILE
from seaway.vessel.frames import GeoOrigin

from seaway_groundstation.tiles import MBTiles, is_mbtiles

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8321
ENV_TOKEN = "SEAWAY_GROUNDSTATION_TOKEN"
DEFAULT_RUNS_DIR = Path("runs")
"""Where recordings are listed for replay: ``runs/`` under the working directory (the launcher's)."""


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
    """Sustained command requests per identity (429 beyond): the operator, and each address
    without the operator token (``guard.py``)."""
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
    runs_dir: Path = DEFAULT_RUNS_DIR
    """The folder whose recordings (``<run>/*.mcap``, ``*.mcap``) the replay view lists; nothing
    outside it is ever opened, except uploads."""
    max_upload_bytes: int = 256 << 20
    """Largest recording that may be uploaded for replay (413 beyond)."""
    upload_dir: Path | None = None
    """Where uploaded recordings are kept (None: a private temporary folder, removed at exit)."""
    max_uploads: int = 8
    """Uploaded recordings kept at once; the oldest is removed first."""
    replay_rate_hz: float = 20.0
    """Frames per second of recorded time a replay is cut into (the live stream's rate)."""
    tiles: str | None = None
    """Map tiles: a URL template with {z}, {x}, {y} (http(s)://...), a local folder laid out
    ``<z>/<x>/<y>.png``, or an MBTiles file (``*.mbtiles``, ``tiles.py``), both served at
    ``/tiles/``; None: no tiles (the map is a metric grid)."""
    model_vessel_file: str = DEFAULT_VESSEL_FILE
    """The run's vessel model file: what the mission check predicts with."""
    run_dir: Path | None = None
    """The run folder of the stack this ground station belongs to: it writes its requests log
    there and reads the launcher's ``mission.json`` (None: neither)."""
    control_period_s: float = CONTROL_PERIOD_S
    """The run's control period [s]: the cross-track sample period of the live metrics (the report's)."""
    alpha_w_per_n2: float | None = None
    """The run's vessel model's alpha [W/N^2], for the paper's energy in the live metrics (None:
    the live metrics give no energy)."""
    clock: Callable[[], float] = time.monotonic
    """Monotonic clock [s] for ages and the rate limit (tests pass their own)."""

    def __post_init__(self) -> None:
        if len(self.token) < 16:
            raise ValueError("the operator token must be at least 16 characters")
        for name in ("max_body_bytes", "max_upload_bytes", "max_uploads", "stream_rate_hz",
                     "replay_rate_hz", "stale_after_s", "request_timeout_s", "control_period_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if self.tiles is not None and not self.tiles.startswith(("http://", "https://")) \
                and not Path(self.tiles).is_dir() \
                and not (is_mbtiles(self.tiles) and Path(self.tiles).is_file()):
            raise ValueError(f"tiles {self.tiles!r}: neither an http(s) URL template, a folder nor an "
                             ".mbtiles file")
        if self.tiles is not None and self.tiles.startswith(("http://", "https://")) \
                and not all(f"{{{k}}}" in self.tiles for k in "zxy"):
            raise ValueError(f"tiles {self.tiles!r}: a URL template needs {{z}}, {{x}} and {{y}}")
        if self.tiles is not None and is_mbtiles(self.tiles):
            MBTiles(self.tiles).close()  # refused now, naming the file, if it cannot be served

    @property
    def tiles_url(self) -> str | None:
        """The template the page loads tiles from (a local folder is served at ``/tiles/``)."""
        if self.tiles is None:
            return None
        if self.tiles.startswith(("http://", "https://")):
            return self.tiles
        return "/tiles/{z}/{x}/{y}" if is_mbtiles(self.tiles) else "/tiles/{z}/{x}/{y}.png"
