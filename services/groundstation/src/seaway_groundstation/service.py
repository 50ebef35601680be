"""``seaway-groundstation``: the thin loop. Opens the bus as the ``groundstation`` identity, serves
the API (``app.create_app``) with uvicorn on 127.0.0.1 unless told otherwise, and prints the page's
address and the operator token once it serves:

    groundstation: http://127.0.0.1:8321/ token <token>

With ``--run-dir`` (a launched ground station, whose output is the run's log) the token goes only
into the address file below, and the line says where it is instead.

The ground station observes every vessel (``seaway/*/...``) and asks for what the operator does;
like the recorder it takes no part in the run agreement, but a launcher's ``--run`` gives it the
run's NED origin (for exporting and drawing missions given in metres) and the model's vessel file
(alpha, for the energy of the live metrics).

With ``--run-dir`` (the launcher's run folder) it writes ``<run_dir>/groundstation/address.json``
(mode 0600: it holds the token; ``seaway.tools.launch.address``) once it serves and before it
declares itself ready, for the launcher (which prints the page's address) or a person to read::

    {"url": "http://127.0.0.1:8321/", "token": "...", "page": "http://127.0.0.1:8321/#token=...",
     "pid": 1234}

and its requests journal beside it (``journal.py``); the replay view lists the recordings of the
folder above it unless ``--runs-dir`` says otherwise.
"""

from __future__ import annotations

import argparse
import logging
import os
import socket
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import uvicorn
from seaway.contract.config import ConfigError
from seaway.runtime import memory
from seaway.runtime.config import parse_service_args, service_parser
from seaway.runtime.service import resolve_run, run_service
from seaway.tools.launch import address
from seaway.tools.launch.address import ENV_TILES
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel

from seaway_groundstation.app import create_app
from seaway_groundstation.config import ENV_TOKEN, GroundStationConfig
from seaway_groundstation.settings import Settings, new_token
from seaway_groundstation.stream import MAX_CLIENT_MESSAGE_BYTES

NAME = "groundstation"
LOOPBACK = ("127.0.0.1", "::1", "localhost")
log = logging.getLogger("seaway_groundstation.service")


def parser() -> argparse.ArgumentParser:
    """The command line: every service's flags and ``GroundStationConfig``'s (``--config FILE``,
    ``--port``, ``--max-body-bytes``, ...)."""
    return service_parser(NAME, "Seaway's ground station: the HTTP/WebSocket API over the bus, for "
                                "every vessel it hears.", GroundStationConfig)


def tiles_of(config: GroundStationConfig) -> str | None:
    """The map tiles: the config's (``--tiles``), else the launcher's ``$SEAWAY_GROUNDSTATION_TILES``."""
    return config.tiles or os.environ.get(ENV_TILES) or None


def write_address(run_dir: Path, page_url: str, token: str) -> Path:
    """``<run_dir>/groundstation/address.json`` for this process, readable by its owner only (it
    holds the token): ``seaway.tools.launch.address``, which the launcher reads it with."""
    return address.write(run_dir, page_url, token, os.getpid())


def vessel_alpha(model_vessel_file: str | None) -> float | None:
    """The model's alpha [W/N^2] for the live metrics' energy (None if the file does not load)."""
    if not model_vessel_file:
        return None
    try:
        return load_vessel(model_vessel_file).alpha_w_per_n2
    except (ConfigError, OSError) as err:
        log.warning("vessel file %s does not load (%s): the live metrics give no energy",
                    model_vessel_file, err)
        return None


def resolve_token(token_file: Path | None) -> str:
    """The operator token: ``token_file``, else ``$SEAWAY_GROUNDSTATION_TOKEN``, else a new one."""
    if token_file is not None:
        try:
            token = token_file.expanduser().read_text(encoding="utf-8").strip()
        except OSError as err:
            raise SystemExit(f"seaway-groundstation: cannot read the token file (token_file, "
                             f"--token-file): {err}") from None
        return token
    return os.environ.get(ENV_TOKEN, "").strip() or new_token()


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: any free one)."""
    family = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][0]
    return socket.create_server((host, port), family=family, backlog=128)


def url(host: str, port: int) -> str:
    return f"http://[{host}]:{port}/" if ":" in host else f"http://{host}:{port}/"


def server_config(app: Any, log_level: str = "info") -> uvicorn.Config:
    """How uvicorn serves the ground station (tests serve it the same way): its WebSocket messages
    from a client bounded to ``stream.MAX_CLIENT_MESSAGE_BYTES`` (the stream takes nothing from
    clients; uvicorn's default is 16 MiB a message)."""
    return uvicorn.Config(app, log_level=log_level, log_config=None, access_log=False, lifespan="on",
                          ws="websockets-sansio", ws_max_size=MAX_CLIENT_MESSAGE_BYTES)


def main(argv: Sequence[str] | None = None) -> int:
    memory.cap_malloc_arenas()  # first, before any thread: off the control path, long-lived
    args, config = parse_service_args(parser(), argv, GroundStationConfig)
    token = resolve_token(config.token_file)
    run = resolve_run(args, NAME)
    origin = run.origin
    try:
        settings = Settings.from_config(
            config.model_copy(update={"tiles": tiles_of(config)}), token=token,
            default_origin=None if origin is None else GeoOrigin.from_degrees(
                origin.lat_deg, origin.lon_deg, origin.alt_m),
            control_period_s=run.control_period_s,
            alpha_w_per_n2=vessel_alpha(run.model_vessel_file),
            model_vessel_file=run.model_vessel_file)
    except ValueError as err:
        print(f"seaway-groundstation: {err}", file=sys.stderr)
        return 2
    host, port_wanted = config.host, config.port
    try:
        sock = bind(host, port_wanted)
    except OSError as err:
        if not (config.port_fallback and port_wanted != 0):
            print(f"seaway-groundstation: cannot listen on {host}:{port_wanted}: {err}", file=sys.stderr)
            return 2
        log.warning("port %d is taken (%s): listening on any free port instead", port_wanted, err)
        sock = bind(host, 0)
    port = sock.getsockname()[1]
    with sock, run_service(NAME, args, run=run, agree=False) as ctx:
        if host not in LOOPBACK:
            log.warning("listening on %s: reachable from other machines; commands still need the "
                        "operator token", host)

        def ready() -> None:
            page = url(host, port)
            written = None
            if settings.run_dir is not None:
                try:
                    written = write_address(settings.run_dir, page, settings.token)
                except OSError as err:
                    log.error("cannot write the address file in %s: %s", settings.run_dir, err)
            ctx.ready()
            # A launched ground station's output is the run's log (logs/groundstation.log): the
            # token goes only into the owner-only address file then; started by hand, to the
            # terminal that started it.
            where = f"the operator token is in {written}" if written else f"token {settings.token}"
            print(f"groundstation: {page} {where}", flush=True)

        app = create_app(ctx.bus, settings, on_ready=ready)
        server = uvicorn.Server(server_config(app, args.log_level.lower()))

        def stop_on_signal() -> None:  # ctx.stop: our own handlers (set before uvicorn's take over)
            ctx.stop.wait()
            server.should_exit = True

        threading.Thread(target=stop_on_signal, name="groundstation-stop", daemon=True).start()
        server.run(sockets=[sock])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
