"""``seaway-groundstation``: the thin loop. Opens the bus as the ``groundstation`` identity, serves
the API (``app.create_app``) with uvicorn on 127.0.0.1 unless told otherwise, and prints the page's
address and the operator token once it serves:

    groundstation: http://127.0.0.1:8321/ token <token>

The ground station observes every vessel (``seaway/*/...``) and asks for what the operator does;
like the recorder it takes no part in the run agreement (it computes nothing from the run), but a
launcher's ``--run`` gives it the run's NED origin for exporting missions given in metres.
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
from seaway.runtime.service import base_parser, parse, resolve_run, run_service
from seaway.vessel.frames import GeoOrigin

from seaway_groundstation.app import create_app
from seaway_groundstation.settings import DEFAULT_HOST, DEFAULT_PORT, ENV_TOKEN, Settings, new_token

NAME = "groundstation"
LOOPBACK = ("127.0.0.1", "::1", "localhost")
log = logging.getLogger("seaway_groundstation.service")


def parser() -> argparse.ArgumentParser:
    ap = base_parser(NAME, "Seaway's ground station: the HTTP/WebSocket API over the bus, for every "
                           "vessel it hears.")
    ap.add_argument("--host", default=DEFAULT_HOST,
                    help=f"address to listen on (default {DEFAULT_HOST}: this machine only)")
    ap.add_argument("--port", type=int, default=DEFAULT_PORT, help=f"TCP port (default {DEFAULT_PORT}; "
                                                                   "0: any free port)")
    ap.add_argument("--token-file", default=None, metavar="FILE",
                    help=f"read the operator token from FILE (default ${ENV_TOKEN}, else a new one "
                         "each start)")
    ap.add_argument("--max-body-bytes", type=int, default=Settings.max_body_bytes,
                    help="largest request body [bytes]")
    ap.add_argument("--rate-limit-per-s", type=float, default=Settings.rate_limit_per_s,
                    help="sustained command requests per client [1/s]")
    ap.add_argument("--rate-limit-burst", type=int, default=Settings.rate_limit_burst,
                    help="command requests a client may make at once")
    ap.add_argument("--request-timeout-s", type=float, default=Settings.request_timeout_s,
                    help="how long a request waits for the vessel's reply [s]")
    return ap


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
    args = parse(parser(), argv)
    token = resolve_token(args)
    run = resolve_run(args, NAME)
    origin = run.origin
    try:
        settings = Settings(
            token=token, max_body_bytes=args.max_body_bytes, rate_limit_per_s=args.rate_limit_per_s,
            rate_limit_burst=args.rate_limit_burst, request_timeout_s=args.request_timeout_s,
            default_origin=None if origin is None else GeoOrigin.from_degrees(
                origin.lat_deg, origin.lon_deg, origin.alt_m))
    except ValueError as err:
        print(f"seaway-groundstation: {err}", file=sys.stderr)
        return 2
    try:
        sock = bind(args.host, args.port)
    except OSError as err:
        print(f"seaway-groundstation: cannot listen on {args.host}:{args.port}: {err}", file=sys.stderr)
        return 2
    port = sock.getsockname()[1]
    with sock, run_service(NAME, args, run=run, agree=False) as ctx:
        if args.host not in LOOPBACK:
            log.warning("listening on %s: reachable from other machines; commands still need the "
                        "operator token", args.host)

        def ready() -> None:
            ctx.ready()
            print(f"groundstation: {url(args.host, port)} token {settings.token}", flush=True)

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
