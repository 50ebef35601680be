"""``seaway router``: the Zenoh router of one side of a boat-shore deployment.

    SEAWAY_CREDENTIALS=/etc/seaway/credentials seaway router --role boat   # deploy/zenoh/boat-router.json5
    seaway router --role shore --connect tls/10.0.0.2:7449 --credentials ~/seaway-credentials/shore
    seaway router --config my-router.json5 --check

Each side runs one router; that side's processes are Zenoh peers that connect to it on loopback
and mesh directly with each other, so the boat's control loop never depends on the router or the
link. The shore router connects to the boat router and retries for ever: when the link comes back,
the shore is back without a restart. See docs/deployment.md.

Which config: ``--config`` (a path, or a file name in deploy/zenoh/), else ``$SEAWAY_ROUTER_CONFIG``,
else ``<role>-router.json5``. Then, in order: ``--connect`` / ``$SEAWAY_ROUTER_CONNECT`` and
``--listen`` / ``$SEAWAY_ROUTER_LISTEN`` (comma-separated endpoints) replace the file's endpoints;
``--cfg KEY=JSON5`` sets any other Zenoh key. A config that speaks TLS (the shipped ones) needs the
side's credentials (``--credentials DIR`` or ``$SEAWAY_CREDENTIALS``: a folder made by ``seaway
credentials create DIR --deployment``): the router is their identity ``router`` and enforces their
access rules, generated from the key registry (``seaway.contract.access``). Its refusals are
counted and answered on ``refusals/router`` like every service's (``seaway health``).

The router logs every session and link that comes and goes (``router <zid> connected``,
``link up: tls/... <-> tls/... (..., authenticated as router)``),
optionally declares a health token (``--health router``, so ``seaway launch`` can wait for it),
and exits 0 within a second or two on SIGINT/SIGTERM. Exit 1: the router could not start (a port
in use, an unreadable certificate); 2: a bad config or argument, or a TLS file missing.
``RUST_LOG=debug`` shows Zenoh's own log (why a TLS handshake was refused, for instance).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import zenoh

from seaway.contract import access, keys
from seaway.contract.config import ConfigError, deploy_path
from seaway.runtime import credentials as creds
from seaway.runtime import refusals
from seaway.runtime.service import (
    DEFAULT_VESSEL,
    ENV_VESSEL,
    add_log_level_option,
    configure_logging,
    install_stop_signals,
)
from seaway.runtime.zenoh_bus import ZenohBus, close_at_exit

log = logging.getLogger("seaway.tools.router")

ENV_ROUTER_CONFIG = "SEAWAY_ROUTER_CONFIG"
ENV_ROUTER_CONNECT = "SEAWAY_ROUTER_CONNECT"
ENV_ROUTER_LISTEN = "SEAWAY_ROUTER_LISTEN"
ROLES = ("boat", "shore")
IDENTITY = access.RELAY
# The TLS settings that name files (zenoh 1.x, transport/link/tls/...).
TLS_FILE_KEYS = ("root_ca_certificate", "listen_certificate", "listen_private_key",
                 "connect_certificate", "connect_private_key")


class RouterConfigError(ValueError):
    """A router config that cannot be used, with the reason in words."""


def resolve_config(name_or_path: str) -> Path:
    """An existing file path as given, else the file of that name in deploy/zenoh/."""
    p = Path(name_or_path)
    if p.is_file():
        return p
    if p.parent == Path("."):
        try:
            candidate = deploy_path("zenoh", p.name)
        except ConfigError:
            candidate = None
        if candidate is not None and candidate.is_file():
            return candidate
        try:
            avail = sorted(x.name for x in deploy_path("zenoh").glob("*.json5"))
        except ConfigError:
            avail = []
        raise RouterConfigError(f"no Zenoh config {name_or_path!r} (neither a file nor in deploy/zenoh/; "
                                f"available: {', '.join(avail) or 'none'})")
    raise RouterConfigError(f"Zenoh config {p} does not exist")


def _get(conf: zenoh.Config, key: str) -> Any:
    return json.loads(conf.get_json(key))


def _endpoints(value: Any, mode: str = "router") -> list[str]:
    """Endpoints as configured: a list, or a per-mode object."""
    if isinstance(value, dict):
        value = value.get(mode) or []
    return list(value or [])


def _split(text: str | None) -> list[str]:
    return [e.strip() for e in (text or "").split(",") if e.strip()]


@dataclass
class RouterSettings:
    """What a router will do, for ``--check`` and for the log at start."""

    config_path: Path
    listen: list[str]
    connect: list[str]
    tls_files: dict[str, str] = field(default_factory=dict)
    mtls: bool = False
    access_control: bool = False
    lease_ms: int | None = None
    side: str = "local"
    """Whose rules its credentials hold (``Credentials.side``): how its health token is named."""

    def summary(self) -> str:
        parts = [f"config {self.config_path}", f"listen {', '.join(self.listen) or '-'}",
                 f"connect {', '.join(self.connect) or '-'}"]
        if self.tls_files:
            parts.append(f"TLS{' with client certificates (mTLS)' if self.mtls else ''}: "
                         + ", ".join(f"{k}={v}" for k, v in sorted(self.tls_files.items())))
        parts.append(f"access control {'on' if self.access_control else 'off'}")
        if self.lease_ms is not None:
            parts.append(f"lease {self.lease_ms} ms")
        return "; ".join(parts)


def build_config(config_path: Path, connect: list[str] | None = None, listen: list[str] | None = None,
                 credentials: creds.Credentials | None = None, overrides: list[str] | None = None,
                 check_files: bool = True) -> tuple[zenoh.Config, RouterSettings]:
    """The router's Zenoh config from a file plus the command-line replacements, checked.

    ``credentials``: the side's folder; its certificate for :data:`IDENTITY` and its access rules
    are added to the config (a ``tls/`` endpoint needs them).
    """
    try:
        conf = zenoh.Config.from_file(str(config_path))
    except Exception as err:  # zenoh's ZError carries the parse position
        raise RouterConfigError(f"Zenoh config {config_path} is invalid: {err}") from None
    mode = _get(conf, "mode")
    if mode is None:
        conf.insert_json5("mode", '"router"')
    elif mode != "router":
        raise RouterConfigError(f"{config_path} has mode {mode!r}; a router config needs mode \"router\" "
                                "(the *-client.json5 files are for the services)")
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
    if listen:
        conf.insert_json5("listen/endpoints", json.dumps(listen))
    if credentials is not None:
        try:
            settings_of = credentials.zenoh_settings(IDENTITY)
        except creds.CredentialsError as err:
            raise RouterConfigError(str(err)) from None
        for key, value in settings_of.items():
            conf.insert_json5(key, json.dumps(value))
    for item in overrides or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise RouterConfigError(f"--cfg {item!r}: expected KEY=JSON5_VALUE, e.g. "
                                    "transport/link/tx/lease=3000")
        try:
            conf.insert_json5(key.strip(), value)
        except Exception as err:
            raise RouterConfigError(f"--cfg {item!r}: {err}") from None
    tls_files = {k: v for k in TLS_FILE_KEYS if (v := _get(conf, f"transport/link/tls/{k}"))}
    settings = RouterSettings(
        config_path=config_path,
        listen=_endpoints(_get(conf, "listen/endpoints")),
        connect=_endpoints(_get(conf, "connect/endpoints")),
        tls_files=tls_files,
        mtls=bool(_get(conf, "transport/link/tls/enable_mtls")),
        access_control=bool(_get(conf, "access_control/enabled")),
        lease_ms=_get(conf, "transport/link/tx/lease"),
        side=credentials.side if credentials is not None else "local",
    )
    uses_tls = any(e.startswith("tls/") for e in settings.listen + settings.connect)
    if uses_tls and credentials is None and "root_ca_certificate" not in tls_files:
        raise RouterConfigError(
            f"{config_path} links over TLS: give the side's credentials (--credentials DIR or "
            f"${creds.ENV_CREDENTIALS}; make them with `seaway credentials create DIR --deployment`, "
            "docs/deployment.md)")
    if check_files:
        missing = [f"{k} {v}" for k, v in tls_files.items() if not Path(v).is_file()]
        if missing:
            raise RouterConfigError("TLS file(s) missing: " + "; ".join(missing))
    return conf, settings


class LinkLogger:
    """Logs sessions (other routers, peers, clients) and their links as they come and go."""

    def __init__(self, session: zenoh.Session) -> None:
        self.session = session
        self.lock = threading.Lock()
        self.up: dict[str, str] = {}  # zid -> whatami of sessions alive now
        self.events = 0
        self._listeners = [
            # history: sessions that came while zenoh.open was still returning count too
            session.info.declare_transport_events_listener(self._on_transport, history=True),
            session.info.declare_link_events_listener(self._on_link, history=True),
        ]

    @staticmethod
    def _is_put(kind: Any) -> bool:
        return kind == zenoh.SampleKind.PUT

    def _on_transport(self, ev: Any) -> None:
        t = ev.transport
        zid, what = str(t.zid), str(t.whatami).rsplit(".", 1)[-1].lower()
        with self.lock:
            self.events += 1
            if self._is_put(ev.kind):
                self.up[zid] = what
            else:
                self.up.pop(zid, None)
            counts = self._counts()
        state = "connected" if self._is_put(ev.kind) else "disconnected"
        level = logging.WARNING if what == "router" and state == "disconnected" else logging.INFO
        log.log(level, "%s %s %s (now: %s)", what, zid, state, counts)

    def _on_link(self, ev: Any) -> None:
        link = ev.link
        state = "up" if self._is_put(ev.kind) else "down"
        log.info("link %s: %s <-> %s (zid %s, interfaces %s%s)", state, link.src, link.dst, link.zid,
                 ",".join(link.interfaces) or "-",
                 f", authenticated as {link.auth_identifier}" if link.auth_identifier else "")

    def _counts(self) -> str:
        by: dict[str, int] = {}
        for w in self.up.values():
            by[w] = by.get(w, 0) + 1
        return ", ".join(f"{n} {w}{'s' if n != 1 else ''}" for w, n in sorted(by.items())) or "nothing"

    def undeclare(self) -> None:
        for listener in self._listeners:
            try:
                listener.undeclare()
            except Exception:
                log.debug("listener undeclare failed", exc_info=True)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="seaway router", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--role", choices=ROLES, default=None,
                    help="boat or shore: picks <role>-router.json5 when no config is named")
    ap.add_argument("--config", default=None,
                    help=f"router config, a path or a name in deploy/zenoh/ (default ${ENV_ROUTER_CONFIG}, "
                         "else <role>-router.json5)")
    ap.add_argument("--connect", action="append", default=None, metavar="ENDPOINT",
                    help="replace the config's connect endpoints (repeatable; default "
                         f"${ENV_ROUTER_CONNECT}, comma-separated)")
    ap.add_argument("--listen", action="append", default=None, metavar="ENDPOINT",
                    help=f"replace the config's listen endpoints (repeatable; default ${ENV_ROUTER_LISTEN})")
    ap.add_argument("--credentials", type=Path, default=None, metavar="DIR",
                    help=f"the side's credentials folder (default ${creds.ENV_CREDENTIALS}; made by "
                         "`seaway credentials create DIR --deployment`)")
    ap.add_argument("--cfg", action="append", default=[], metavar="KEY=JSON5",
                    help="set one Zenoh config key, e.g. --cfg transport/link/tx/lease=3000")
    ap.add_argument("--vessel", default=os.environ.get(ENV_VESSEL, DEFAULT_VESSEL),
                    help="vessel name for the health token")
    ap.add_argument("--health", default=None, choices=keys.SERVICES, metavar="SERVICE",
                    help="declare the health token "
                         f"{keys.health_wildcard('<vessel>').replace('*', 'SERVICE')} once the router "
                         "is up (the profiles use 'launcher')")
    ap.add_argument("--check", action="store_true", help="check the config, print what it does, exit")
    add_log_level_option(ap)
    return ap


def config_from_args(args: argparse.Namespace) -> tuple[zenoh.Config, RouterSettings]:
    name = args.config or os.environ.get(ENV_ROUTER_CONFIG) or (
        f"{args.role}-router.json5" if args.role else None)
    if not name:
        raise RouterConfigError(f"name a config: --role boat|shore, --config FILE or ${ENV_ROUTER_CONFIG}")
    connect = args.connect or _split(os.environ.get(ENV_ROUTER_CONNECT)) or None
    listen = args.listen or _split(os.environ.get(ENV_ROUTER_LISTEN)) or None
    given: creds.Credentials | str | None = (creds.Credentials(args.credentials.expanduser())
                                             if args.credentials else creds.from_env())
    if given == creds.NONE:
        given = None
    return build_config(resolve_config(name), connect, listen, given,  # type: ignore[arg-type]
                        args.cfg)


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    configure_logging("router", args.log_level)
    try:
        conf, settings = config_from_args(args)
    except (RouterConfigError, ConfigError, creds.CredentialsError) as err:
        print(f"seaway router: {err}", file=sys.stderr)
        return 2
    if args.check:
        print(f"router config valid: {settings.summary()}")
        return 0
    stop = threading.Event()
    install_stop_signals(stop)
    # Zenoh's own log (RUST_LOG=debug shows, e.g., why a TLS handshake was refused), read for
    # the refusals of the access rules when there are any.
    if not (settings.access_control and refusals.watch(IDENTITY)):
        zenoh.init_log_from_env_or("error")
    log.info("starting: %s", settings.summary())
    t0 = time.monotonic()
    try:
        session = close_at_exit(zenoh.open(conf))
    except Exception as err:  # a port in use, an unreadable certificate, ...
        log.error("could not start the router: %s", err)
        return 1
    links = LinkLogger(session)
    token = None
    if settings.access_control:
        refusals.serve(ZenohBus(session, args.vessel), IDENTITY)
    try:
        health = keys.health_key(args.vessel, args.health, settings.side) if args.health else ""
        if health:
            token = session.liveliness().declare_token(health)
        log.info("router %s up in %.2f s%s", session.info.zid(), time.monotonic() - t0,
                 f", health token {health}" if health else "")
        # Not one blocking wait: a signal may land on any of Zenoh's threads, and Python runs its
        # handler only when the main thread does (a SIGINT then went unanswered, 1 stop in ~30).
        while not stop.wait(0.25):
            pass
    finally:
        t_stop = time.monotonic()
        links.undeclare()
        if token is not None:
            try:
                token.undeclare()
            except Exception:
                log.debug("token undeclare failed", exc_info=True)
        session.close()
        log.info("router stopped in %.2f s", time.monotonic() - t_stop)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
