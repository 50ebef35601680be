"""The ground station's settings as ``create_app`` takes them: the configuration
(``config.GroundStationConfig``: its defaults and bounds are defined there, once), the operator
token, the run's facts, and the clock."""

from __future__ import annotations

import dataclasses
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import ValidationError
from seaway.contract.config import describe_validation_error
from seaway.runtime.run import CONTROL_PERIOD_S, DEFAULT_VESSEL_FILE
from seaway.vessel.frames import GeoOrigin

from seaway_groundstation.config import DEFAULT_RUNS_DIR, GroundStationConfig
from seaway_groundstation.tiles import MBTiles, is_mbtiles

_DEFAULT = GroundStationConfig()


def new_token() -> str:
    """A fresh operator token (URL-safe, 256 bits)."""
    return secrets.token_urlsafe(32)


@dataclass(frozen=True)
class Settings:
    """What ``create_app`` needs besides the bus: ``GroundStationConfig``'s fields (described
    there), the token, the run's facts and the clock. ``from_config`` makes it from a config.
    """

    token: str = field(default_factory=new_token, repr=False)
    """Operator token: ``Authorization: Bearer <token>`` on every request that moves or changes a
    vessel. Generated at start unless configured."""
    max_body_bytes: int = _DEFAULT.max_body_bytes
    rate_limit_per_s: float = _DEFAULT.rate_limit_per_s
    rate_limit_burst: int = _DEFAULT.rate_limit_burst
    request_timeout_s: float = _DEFAULT.request_timeout_s
    stream_rate_hz: float = _DEFAULT.stream_rate_hz
    max_stream_clients: int = _DEFAULT.max_stream_clients
    stream_send_timeout_s: float = _DEFAULT.stream_send_timeout_s
    max_vessels: int = _DEFAULT.max_vessels
    forget_after_s: float = _DEFAULT.forget_after_s
    stale_after_s: float = _DEFAULT.stale_after_s
    max_waypoints: int = _DEFAULT.max_waypoints
    default_origin: GeoOrigin | None = None
    """NED origin for exporting metre waypoints when a vessel has published none (the run's)."""
    scenario_dir: Path | None = None
    """Where scenarios named in a request are read (None: the checkout's deploy/scenarios)."""
    runs_dir: Path = DEFAULT_RUNS_DIR
    """The folder whose recordings (``<run>/*.mcap``, ``*.mcap``) the replay view lists
    (``GroundStationConfig.runs_folder``); nothing outside it is ever opened, except uploads."""
    max_upload_bytes: int = _DEFAULT.max_upload_bytes
    upload_dir: Path | None = _DEFAULT.upload_dir
    max_uploads: int = _DEFAULT.max_uploads
    replay_rate_hz: float = _DEFAULT.replay_rate_hz
    tiles: str | None = _DEFAULT.tiles
    """Map tiles: a URL template with {z}, {x}, {y} (http(s)://...), a local folder laid out
    ``<z>/<x>/<y>.png``, or an MBTiles file (``*.mbtiles``, ``tiles.py``), both served at
    ``/tiles/``; None: no tiles (the map is a metric grid)."""
    model_vessel_file: str = DEFAULT_VESSEL_FILE
    """The run's vessel model file: what the mission check predicts with."""
    run_dir: Path | None = _DEFAULT.run_dir
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
        try:  # the configuration's own bounds, whoever made these settings
            GroundStationConfig(**{name: getattr(self, name) for name in CONFIGURED})
        except ValidationError as err:
            raise ValueError(describe_validation_error(err, "ground station settings")) from None
        if not self.control_period_s > 0:
            raise ValueError(f"control_period_s must be > 0, got {self.control_period_s}")
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

    @classmethod
    def from_config(cls, config: GroundStationConfig, *, token: str, **run_facts: object) -> Settings:
        """The settings of ``config``, with ``token`` and the run's facts (``default_origin``,
        ``control_period_s``, ``alpha_w_per_n2``, ``model_vessel_file``)."""
        fields = {name: getattr(config, name) for name in CONFIGURED}
        fields["runs_dir"] = config.runs_folder()
        return cls(token=token, **fields, **run_facts)  # type: ignore[arg-type]

    @property
    def tiles_url(self) -> str | None:
        """The template the page loads tiles from (a local folder is served at ``/tiles/``)."""
        if self.tiles is None:
            return None
        if self.tiles.startswith(("http://", "https://")):
            return self.tiles
        return "/tiles/{z}/{x}/{y}" if is_mbtiles(self.tiles) else "/tiles/{z}/{x}/{y}.png"


CONFIGURED = tuple(f.name for f in dataclasses.fields(Settings)
                   if f.name in GroundStationConfig.model_fields)
"""The settings that are ``GroundStationConfig``'s fields: taken from it, checked against its bounds."""
