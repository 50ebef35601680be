"""The ground station's configuration, made the way every service's is (``seaway.runtime.config``):
the defaults below, then ``--config FILE`` (TOML or JSON; an unknown field is an error naming it),
then the flags (``--port``, ``--max-body-bytes``, ...), each checked against its field's bounds.

The operator token is not a setting here: it comes from ``--token-file``, else
``$SEAWAY_GROUNDSTATION_TOKEN``, else a new one each start, and is never written to a config file.
The run's facts (its NED origin, the model's vessel file, the control period) come from ``--run``
(``seaway.runtime.run``), as for the back-end services. ``Settings`` (``settings.py``) is this plus
those, as ``create_app`` takes it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import Field
from seaway.contract.config import ConfigModel
from seaway.runtime.config import Flag
from seaway.tools.launch.address import ENV_TILES

from seaway_groundstation.fleet import FORGET_AFTER_S

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8321
DEFAULT_RUNS_DIR = Path("runs")
"""Where recordings are listed for replay: ``runs/`` under the working directory (the launcher's)."""
ENV_TOKEN = "SEAWAY_GROUNDSTATION_TOKEN"


class GroundStationConfig(ConfigModel):
    """What the ground station serves with. Times in seconds, sizes in bytes, rates in requests (or
    frames) per second."""

    host: Annotated[str, Flag()] = Field(
        default=DEFAULT_HOST, min_length=1,
        description=f"address to listen on; {DEFAULT_HOST} is this machine only")
    port: Annotated[int, Flag()] = Field(
        default=DEFAULT_PORT, ge=0, le=65535, description="TCP port (0: any free port)")
    port_fallback: Annotated[bool, Flag()] = Field(
        default=False,
        description="if the port is taken, listen on any free port instead of failing (the address "
                    "is printed and written to the address file)")
    token_file: Annotated[Path | None, Flag(metavar="FILE")] = Field(
        default=None,
        description=f"read the operator token from FILE (default ${ENV_TOKEN}, else a new one each "
                    "start)")
    max_body_bytes: Annotated[int, Flag()] = Field(
        default=1 << 20, ge=1, description="largest request body accepted (413 beyond) [bytes]")
    rate_limit_per_s: Annotated[float, Flag()] = Field(
        default=5.0, gt=0,
        description="sustained command requests per identity, the operator and each address "
                    "without the operator token (429 beyond) [1/s]")
    rate_limit_burst: Annotated[int, Flag()] = Field(
        default=20, ge=1,
        description="command requests a client may make at once before the sustained rate applies")
    request_timeout_s: Annotated[float, Flag()] = Field(
        default=10.0, gt=0, description="how long a request waits for the vessel's reply (504 after) [s]")
    stream_rate_hz: float = Field(
        default=20.0, gt=0, description="most frames per second a stream client gets [Hz]")
    max_stream_clients: int = Field(
        default=256, ge=1, description="stream (WebSocket) clients served at once")
    stream_send_timeout_s: float = Field(
        default=10.0, gt=0,
        description="a stream client that has not taken a frame within this is dropped (closed "
                    "with 1008 and the reason if that still goes out, else cut), freeing its place [s]")
    max_vessels: int = Field(
        default=64, ge=1,
        description="vessels the ground station keeps at once; a new name beyond it is refused "
                    "(counted, logged) unless a vessel silent and without services can be forgotten")
    forget_after_s: float = Field(
        default=FORGET_AFTER_S, ge=0,
        description="how long a vessel without any service's health token must have been silent "
                    "before a new name may take its place when max_vessels are kept [s]")
    stale_after_s: float = Field(
        default=2.0, gt=0, description="a message older than this is shown as stale [s]")
    max_waypoints: int = Field(
        default=1000, ge=2, description="most waypoints a mission sent through the API may have")
    run_dir: Annotated[Path | None, Flag(metavar="DIR")] = Field(
        default=None,
        description="the run folder: write groundstation/address.json (0600) and the requests "
                    "journal there, read the launcher's mission.json")
    runs_dir: Annotated[Path | None, Flag(metavar="DIR")] = Field(
        default=None,
        description=f"where the replay view lists recordings (default: the folder holding the run "
                    f"folder, else {DEFAULT_RUNS_DIR}/ in the working directory); nothing outside "
                    "it is opened, except uploads")
    tiles: Annotated[str | None, Flag(metavar="URL|DIR|FILE")] = Field(
        default=None,
        description="map tiles: a URL template with {z}/{x}/{y}, a folder <z>/<x>/<y>.png or an "
                    f"MBTiles file (*.mbtiles) served here (default ${ENV_TILES}, else none: a "
                    "metric grid)")
    max_upload_bytes: Annotated[int, Flag()] = Field(
        default=256 << 20, ge=1,
        description="largest recording that may be uploaded for replay (413 beyond) [bytes]")
    upload_dir: Path | None = Field(
        default=None,
        description="where uploaded recordings are kept (default: a private temporary folder, "
                    "removed at exit)")
    max_uploads: int = Field(
        default=8, ge=1, description="uploaded recordings kept at once; the oldest is removed first")
    replay_rate_hz: float = Field(
        default=20.0, gt=0,
        description="frames per second of recorded time a replay is cut into (the live stream's "
                    "rate) [Hz]")

    def runs_folder(self) -> Path:
        """The folder the replay view lists: ``runs_dir``, else the one holding ``run_dir``, else
        ``DEFAULT_RUNS_DIR``."""
        if self.runs_dir is not None:
            return self.runs_dir
        return self.run_dir.parent if self.run_dir is not None else DEFAULT_RUNS_DIR
