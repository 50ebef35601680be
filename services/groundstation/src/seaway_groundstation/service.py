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

import uvicorn
from seaway.contract.config import ConfigError
from seaway.runtime import memory
from seaway.runtime.argtypes import positive_float, positive_int, whole_number
from seaway.runtime.service import base_parser, parse, resolve_run, run_service
from seaway.tools.launch import address
from seaway.tools.launch.address import ENV_TILES
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import load_vessel

from seaway_groundstation.app import create_app
from seaway_groundstation.settings import (
    DEFAULT_HOST,
    DEFAULT_PORT,
    DEFAULT_RUNS_DIR,
    ENV_TOKEN,
    Settings,
    new_token,
)

NAME = "groundstation"
LOOPBACK = ("127.0.0.1", "::1", "localhost")
log = logging.getLogger("seaway_groundstation.service")


def parser() -> argparse.ArgumentParser:
    ap = base_parser(NAME, "Seaway's ground station: the HTTP/WebSocket API over the bus, for every "
                           "vessel it hears.")
    ap.add_argument("--host", default=DEFAULT_HOST,
                    help=f"address to listen on (default {DEFAULT_HOST}: this machine only)")
    ap.add_argument("--port", type=whole_number(0, 65535), default=DEFAULT_PORT,
                    help=f"TCP port (default {DEFAULT_PORT}; 0: any free port)")
    ap.add_argument("--port-fallback", action="store_true",
                    help="if --port is taken, listen on any free port instead of failing (the "
                         "address is printed and written to the address file)")
    ap.add_argument("--token-file", default=None, metavar="FILE",
                    help=f"read the operator token from FILE (default ${ENV_TOKEN}, else a new one "
                         "each start)")
    ap.add_argument("--max-body-bytes", type=positive_int, default=Settings.max_body_bytes,
                    help="largest request body [bytes]")
    ap.add_argument("--rate-limit-per-s", type=positive_float, default=Settings.rate_limit_per_s,
                    help="sustained command requests per identity (the operator; each address "
                         "without the token) [1/s]")
    ap.add_argument("--rate-limit-burst", type=positive_int, default=Settings.rate_limit_burst,
                    help="command requests a client may make at once")
    ap.add_argument("--request-timeout-s", type=positive_float, default=Settings.request_timeout_s,
                    help="how long a request waits for the vessel's reply [s]")
    ap.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                    help="the run folder: write groundstation/address.json (0600) and the requests "
                         "journal there, read the launcher's mission.json")
    ap.add_argument("--runs-dir", type=Path, default=None, metavar="DIR",
                    help=f"where the replay view lists recordings (default: the folder holding "
                         f"--run-dir, else {DEFAULT_RUNS_DIR}/ here)")
    ap.add_argument("--tiles", default=os.environ.get(ENV_TILES) or None, metavar="URL|DIR|FILE",
                    help="map tiles: a URL template with {z}/{x}/{y}, a folder <z>/<x>/<y>.png or an "
                         f"MBTiles file (*.mbtiles) served here (default ${ENV_TILES}, else none: "
                         "a metric grid)")
    ap.add_argument("--max-upload-bytes", type=positive_int, default=Settings.max_upload_bytes,
                    help="largest recording that may be uploaded for replay [bytes]")
    return ap


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


def resolve_token(args: argparse.Namespace) -> str:
    """The operator token: ``--token-file``, else ``$SEAWAY_GROUNDSTATION_TOKEN``, else a new one."""
    if args.token_file:
        try:
            token = Path(args.token_file).expanduser().read_text(encoding="utf-8").strip()
        except OSError as err:
            raise SystemExit(f"seaway-groundstation: cannot read --token-file: {err}") from None
        return token
    return os.environ.get(ENV_TOKEN, "").strip() or new_token()


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: any free one)."""
    family = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][0]
    return socket.create_server((host, port), family=family, backlog=128)


def url(host: str, port: int) -> str:
    return f"http://[{host}]:{port}/" if ":" in host else f"http://{host}:{port}/"


def main(argv: Sequence[str] | None = None) -> int:
    memory.cap_malloc_arenas()  # first, before any thread: off the control path, long-lived
    args = parse(parser(), argv)
    token = resolve_token(args)
    run = resolve_run(args, NAME)
    origin = run.origin
    runs_dir = args.runs_dir or (args.run_dir.parent if args.run_dir is not None else DEFAULT_RUNS_DIR)
    try:
        settings = Settings(
            token=token, max_body_bytes=args.max_body_bytes, rate_limit_per_s=args.rate_limit_per_s,
            rate_limit_burst=args.rate_limit_burst, request_timeout_s=args.request_timeout_s,
            default_origin=None if origin is None else GeoOrigin.from_degrees(
                origin.lat_deg, origin.lon_deg, origin.alt_m),
            runs_dir=runs_dir, run_dir=args.run_dir, tiles=args.tiles,
            max_upload_bytes=args.max_upload_bytes, control_period_s=run.control_period_s,
            alpha_w_per_n2=vessel_alpha(run.model_vessel_file),
            model_vessel_file=run.model_vessel_file)
    except ValueError as err:
        print(f"seaway-groundstation: {err}", file=sys.stderr)
        return 2
    try:
        sock = bind(args.host, args.port)
    except OSError as err:
        if not (args.port_fallback and args.port != 0):
            print(f"seaway-groundstation: cannot listen on {args.host}:{args.port}: {err}", file=sys.stderr)
            return 2
        log.warning("port %d is taken (%s): listening on any free port instead", args.port, err)
        sock = bind(args.host, 0)
    port = sock.getsockname()[1]
    with sock, run_service(NAME, args, run=run, agree=False) as ctx:
        if args.host not in LOOPBACK:
            log.warning("listening on %s: reachable from other machines; commands still need the "
                        "operator token", args.host)

        def ready() -> None:
            page = url(args.host, port)
            written = None
            if args.run_dir is not None:
                try:
                    written = write_address(args.run_dir, page, settings.token)
                except OSError as err:
                    log.error("cannot write the address file in %s: %s", args.run_dir, err)
            ctx.ready()
            # A launched ground station's output is the run's log (logs/groundstation.log): the
            # token goes only into the owner-only address file then; started by hand, to the
            # terminal that started it.
            where = f"the operator token is in {written}" if written else f"token {settings.token}"
            print(f"groundstation: {page} {where}", flush=True)

        app = create_app(ctx.bus, settings, on_ready=ready)
        server = uvicorn.Server(uvicorn.Config(app, log_level=args.log_level.lower(), log_config=None,
                                               access_log=False, lifespan="on", ws="websockets-sansio"))

        def stop_on_signal() -> None:  # ctx.stop: our own handlers (set before uvicorn's take over)
            ctx.stop.wait()
            server.should_exit = True

        threading.Thread(target=stop_on_signal, name="groundstation-stop", daemon=True).start()
        server.run(sockets=[sock])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
