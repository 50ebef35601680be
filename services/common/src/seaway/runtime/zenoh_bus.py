"""The bus on Zenoh: sessions from config files, and ``ZenohBus``, the transport of every process.

* ``open_session``: a Zenoh session from a config file (default: the packaged peer-on-loopback
  config, multicast scouting off; ``SEAWAY_ZENOH_CONFIG`` names another file,
  ``SEAWAY_ZENOH_RENDEZVOUS`` moves the default's rendezvous port), as one identity of the stack:
  mutual TLS with that identity's certificate and the stack's access rules
  (``seaway.runtime.credentials``). The credentials come from the caller, else
  ``$SEAWAY_CREDENTIALS``, else the stack registered on the rendezvous endpoint
  (``seaway.runtime.stacks``); none at all is an error, ``$SEAWAY_CREDENTIALS=none`` opts out.
* Every session opened here is closed before the interpreter joins its threads at exit
  (``close_at_exit``): zenoh-python serves each subscriber callback on a non-daemon thread that ends
  only when its session closes, so one session left open (a service that raised, a test that failed
  before its cleanup) kept the process alive for ever.
* ``ZenohBus``: the byte-level primitives of ``seaway.runtime.bus.Bus`` on one session; the typed
  layer (validation, refusals, counters) is the interface's own, shared with the in-memory bus.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import threading
from collections.abc import Callable, Iterator
from importlib import resources
from pathlib import Path
from typing import Any

import zenoh
import zenoh.ext

from seaway.contract.messages import JSON_ENCODING
from seaway.runtime import credentials as creds
from seaway.runtime import stacks
from seaway.runtime.bus import Bus, RuntimeEnvError
from seaway.runtime.bus_raw import RAW_ENCODING, Declared, RawPublisher, RawReply, RawSample

log = logging.getLogger("seaway.runtime.bus")

ENV_CONFIG = "SEAWAY_ZENOH_CONFIG"
ENV_RENDEZVOUS = "SEAWAY_ZENOH_RENDEZVOUS"
DEFAULT_RENDEZVOUS = "tcp/127.0.0.1:7447"
ENV_RUNTIME = "ZENOH_RUNTIME"
"""Zenoh's own variable for its thread pools (RON: one entry per runtime, read once per process)."""
LOCKSTEP_RUNTIME = ("(app: (worker_threads: 1), acc: (handover: app), tx: (handover: app), "
                    "rx: (handover: app), net: (handover: app))")
"""The Zenoh threads of a lockstep stack's processes: one worker thread for all of Zenoh's runtimes
(by default each has its own: receive, transmit, accept, network, application; 6-7 threads).

Why: a lockstep period is a chain of hand-overs, and with a pool per runtime each hand-over wakes
a transmit thread in the sender and a receive thread in the receiver: dozens of thread switches per
period across a stack, a large share of a small machine's CPU spent switching. With one thread per
process a put queues the bundle and the same thread writes it once the callback returns, which
halves the switches per period (``seaway bench lockstep`` measures the wall time it saves).

Safe only where no callback run on Zenoh's thread (``subscribe_raw(inline=True)``) waits for Zenoh
itself: a lockstep member's intake answers and publishes, never waits for a reply, and publishes no
more express samples than a link's queue holds (``LOCKSTEP_TX_QUEUE``). Every process
of a lockstep run takes it (``use_lockstep_runtime``: the services' shared loop and the launcher)
unless ``$ZENOH_RUNTIME`` is set; real time keeps Zenoh's defaults."""


LOCKSTEP_TX_QUEUE = 16
"""Batches a link may queue for the data priority (``transport/link/tx/queue/size/data``; Zenoh's
maximum, its default 2) in a session whose process sets ``$ZENOH_RUNTIME`` (``LOCKSTEP_RUNTIME``, or a
user's own, which may be one thread too).

Why: on one thread nothing is sent while a callback runs on it, and each express put takes a batch
of every link's queue until the callback returns. With the default 2, the third put of a callback
waits for ever: a lockstep member repeating three bundles for a restarted recorder would stop, its
health token lapse and the stack stall. A member's repeat
sends at most ``lockstep_member.KEPT_BUNDLES``, plus its answer, and one intake can take two repeats."""


def use_lockstep_runtime() -> None:
    """This process's Zenoh on one thread (``LOCKSTEP_RUNTIME``), unless ``$ZENOH_RUNTIME`` says
    otherwise; before its first session opens (Zenoh reads the variable once), and inherited by the
    processes it starts."""
    os.environ.setdefault(ENV_RUNTIME, LOCKSTEP_RUNTIME)


def default_config_text() -> str:
    return resources.files("seaway.runtime").joinpath("zenoh/peer-loopback.json5").read_text()


def rendezvous_endpoint() -> str:
    """The default config's rendezvous endpoint (``$SEAWAY_ZENOH_RENDEZVOUS`` or port 7447), as TCP."""
    return os.environ.get(ENV_RENDEZVOUS) or DEFAULT_RENDEZVOUS


def resolve_credentials(given: creds.Credentials | str | None = None,
                        rendezvous: str | None = None) -> creds.Credentials | None:
    """The credentials a session uses: ``given``, else ``$SEAWAY_CREDENTIALS``, else those of the
    stack registered on the rendezvous endpoint (``rendezvous``, else ``rendezvous_endpoint()``);
    None only when opted out (``none``).

    Raises ``CredentialsError`` when there are none, naming the ways to get some.
    """
    found = given if given is not None else creds.from_env()
    if found is None:
        entry = stacks.lookup(rendezvous or rendezvous_endpoint())
        if entry is not None:
            found = entry.session_credentials()
    if found is None:
        raise creds.CredentialsError(
            f"no credentials: no stack runs on {rendezvous or rendezvous_endpoint()} and "
            f"${creds.ENV_CREDENTIALS} is not set. Start the stack with `seaway launch` (it creates "
            "the run's credentials), "
            f"or set ${creds.ENV_CREDENTIALS} to a folder made by `seaway credentials create`, or "
            f"to '{creds.NONE}' to run without authentication")
    return None if found == creds.NONE else found  # type: ignore[return-value]


def _secure_endpoints(conf: zenoh.Config) -> None:
    # The packaged default speaks plain TCP on loopback; with credentials the same ports speak TLS.
    for where in ("listen/endpoints", "connect/endpoints"):
        eps = json.loads(conf.get_json(where))
        conf.insert_json5(where, json.dumps([e.replace("tcp/", "tls/", 1) if e.startswith("tcp/") else e
                                             for e in eps]))


def load_zenoh_config(path: str | Path | None = None, identity: str | None = None,
                      credentials: creds.Credentials | str | None = None,
                      rendezvous: str | None = None) -> zenoh.Config:
    """Zenoh config from ``path``, else ``$SEAWAY_ZENOH_CONFIG``, else the packaged default, made
    ``identity``'s session of the stack (``resolve_credentials``).

    ``identity``: else ``$SEAWAY_IDENTITY``, else ``operator``. ``rendezvous``, else
    ``$SEAWAY_ZENOH_RENDEZVOUS``, replaces the rendezvous endpoint of the packaged default only (a
    process talking to several stacks, each on its own, names each one's here; then
    ``$SEAWAY_ZENOH_CONFIG`` is not read, a ``path`` with it is a ValueError); with credentials the default's
    endpoints are TLS (a file's endpoints are used as written).
    """
    identity = identity or os.environ.get(creds.ENV_IDENTITY) or "operator"
    if path is not None and rendezvous:
        raise ValueError(f"a Zenoh config ({path}) names its own endpoints: give it or a "
                         f"rendezvous ({rendezvous}), not both")
    # A rendezvous named here is the packaged default's: the environment's config would drop it.
    path = path or (None if rendezvous else os.environ.get(ENV_CONFIG)) or None
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"Zenoh config {p} does not exist")
        try:
            conf = zenoh.Config.from_file(str(p))
        except Exception as err:  # zenoh raises its own ZError with the parse position
            raise ValueError(f"Zenoh config {p} is invalid: {err}") from None
    else:
        conf = zenoh.Config.from_json5(default_config_text())
        rendezvous = rendezvous or os.environ.get(ENV_RENDEZVOUS)
        if rendezvous:
            conf.insert_json5("listen/endpoints", json.dumps([rendezvous, "tcp/127.0.0.1:0"]))
            conf.insert_json5("connect/endpoints", json.dumps([rendezvous]))
    # Every sample stamped by its publisher: a real-time topic's publisher keeps a cache for a
    # restarted recorder (Bus.raw_publisher), which zenoh-ext orders by these stamps.
    conf.insert_json5("timestamping/enabled", "true")
    if path is not None and not _speaks_tls(conf):
        # A deployment file that links its processes over plain TCP has no certificate to match:
        # the access rules would refuse everything. Its own rules (or none) stand; say so.
        log.warning("Zenoh config %s links over plain TCP: the stack's credentials are not used "
                    "(use a TLS config for authentication)", path)
        return conf
    found = resolve_credentials(credentials, rendezvous)
    if found is None and path is not None:
        raise creds.CredentialsError(
            f"Zenoh config {path} links over TLS: it needs the side's credentials, not "
            f"${creds.ENV_CREDENTIALS}={creds.NONE} (make them with `seaway credentials create DIR "
            "--deployment`, docs/deployment.md)")
    if found is None:
        log.warning("authentication OFF ($%s=%s): any process on this machine may publish and "
                    "command on this stack", creds.ENV_CREDENTIALS, creds.NONE)
        return conf
    for key, value in found.zenoh_settings(identity).items():
        conf.insert_json5(key, json.dumps(value))
    if path is None:
        _secure_endpoints(conf)
    return conf


def _speaks_tls(conf: zenoh.Config) -> bool:
    eps = [*json.loads(conf.get_json("listen/endpoints")), *json.loads(conf.get_json("connect/endpoints"))]
    return any(str(e).startswith("tls/") for e in eps)


def open_session(config_path: str | Path | None = None, identity: str | None = None,
                 credentials: creds.Credentials | str | None = None,
                 rendezvous: str | None = None) -> zenoh.Session:
    config = load_zenoh_config(config_path, identity, credentials, rendezvous)
    if os.environ.get(ENV_RUNTIME):  # ours or a user's own: either may be one thread
        config.insert_json5("transport/link/tx/queue/size/data", str(LOCKSTEP_TX_QUEUE))
    try:
        session = zenoh.open(config)
    except BaseException as err:
        # Zenoh reads $ZENOH_RUNTIME when its first thread pool starts and panics on a bad value
        # (pyo3's PanicException, not an Exception): say which variable and what it takes.
        value = os.environ.get(ENV_RUNTIME)
        if value is None or type(err).__name__ != "PanicException":
            raise
        raise RuntimeEnvError(
            f"${ENV_RUNTIME}={value!r} is not a Zenoh runtime setting ({err}); it is RON with one "
            f"entry per runtime (app, acc, tx, rx, net), e.g. {LOCKSTEP_RUNTIME!r}, what a "
            f"lockstep stack gets by default; unset it for Zenoh's defaults") from None
    return close_at_exit(session)


# Strong references (a Session takes no weak one); closed sessions are dropped at each new open.
_open_sessions: list[zenoh.Session] = []
_exit_hook_lock = threading.Lock()
_exit_hook_registered = False


def close_at_exit(session: zenoh.Session) -> zenoh.Session:
    """``session``, to be closed when the interpreter exits, before it joins non-daemon threads.

    ``atexit`` is too late: it runs after that join, which waits for ever on the callback threads of
    an open session. ``threading._register_atexit`` (CPython 3.9+, what ``concurrent.futures`` uses
    for its workers) runs before it.
    """
    global _exit_hook_registered
    with _exit_hook_lock:
        _open_sessions[:] = [s for s in _open_sessions if not s.is_closed()]
        _open_sessions.append(session)
        if not _exit_hook_registered:
            threading._register_atexit(_close_open_sessions)  # type: ignore[attr-defined]
            _exit_hook_registered = True
    return session


def _close_open_sessions() -> None:
    with _exit_hook_lock:
        sessions = list(_open_sessions)
    for session in sessions:
        try:
            if not session.is_closed():
                session.close()
        except Exception:  # exiting anyway: one session's error must not keep the others open
            log.debug("closing a Zenoh session at exit failed", exc_info=True)


def _replies(handler: Iterator[Any]) -> Iterator[RawReply]:
    for r in handler:
        if r.ok is not None:
            yield RawReply(str(r.ok.key_expr), r.ok.payload.to_bytes())
        else:
            yield RawReply("", r.err.payload.to_bytes(), r.err.payload.to_string())


class _Ring:
    """``RawRing`` on a Zenoh subscriber whose handler is a ring channel."""

    def __init__(self, sub: zenoh.Subscriber) -> None:
        self._sub = sub

    def take(self) -> bytes | None:
        sample = self._sub.try_recv()
        return None if sample is None else sample.payload.to_bytes()

    def take_carried(self) -> tuple[bytes, Any] | None:
        payload = self.take()
        return None if payload is None else (payload, None)  # bytes from another process only

    def undeclare(self) -> None:
        self._sub.undeclare()


class ZenohBus(Bus):
    """One process's Zenoh session, typed by ``Bus``. ``session`` is there for Zenoh-only tools."""

    def __init__(self, session: zenoh.Session, vessel: str) -> None:
        super().__init__(vessel)
        self.session = session
        # Zenoh keeps callback entities alive by itself; holding them too makes that explicit.
        self._entities: list[Any] = []

    @classmethod
    def connect(cls, vessel: str, config_path: str | Path | None = None, identity: str | None = None,
                credentials: creds.Credentials | str | None = None,
                rendezvous: str | None = None) -> ZenohBus:
        """A new session from ``config_path`` as ``identity`` (see ``load_zenoh_config``), on the
        side its credentials' rules say (``Bus.side``)."""
        bus = cls(open_session(config_path, identity, credentials, rendezvous), vessel)
        with contextlib.suppress(creds.CredentialsError):  # none (a plain-TCP config): local
            found = resolve_credentials(credentials, rendezvous)
            if found is not None:
                bus.side = found.side
        return bus

    def raw_publisher(self, key: str, encoding: str = RAW_ENCODING, *, block: bool = False,
                      express: bool = False, cache: int = 0) -> RawPublisher:
        # Only a blocking publisher names its congestion control: the others keep Zenoh's default.
        extra: dict[str, Any] = {"congestion_control": zenoh.CongestionControl.BLOCK} if block else {}
        if express:
            extra["express"] = True
        if cache > 0:
            # zenoh-ext's cache, answered to an advanced subscriber's history query; detectable
            # (a liveliness token), so a subscriber that joins later asks it.
            pub: Any = zenoh.ext.declare_advanced_publisher(
                self.session, key, encoding=zenoh.Encoding(encoding),
                cache=zenoh.ext.CacheConfig(max_samples=cache), publisher_detection=True, **extra)
        else:
            pub = self.session.declare_publisher(key, encoding=zenoh.Encoding(encoding), **extra)
        self._entities.append(pub)
        return pub

    def subscribe_raw(self, keyexpr: str, callback: Callable[[RawSample], None], *,
                      inline: bool = False, history_s: float = 0.0) -> Declared:
        def on_sample(sample: zenoh.Sample) -> None:
            stamp = sample.timestamp
            callback(RawSample(str(sample.key_expr), sample.payload.to_bytes(), str(sample.encoding),
                               None if stamp is None else stamp.get_time_as_ntp64().as_nanos()))

        # A plain callable is run by zenoh-python on a Python thread of its own (one hand-off per
        # sample); ``indirect=False`` runs it on Zenoh's receive thread itself.
        handler: Any = zenoh.handlers.Callback(on_sample, indirect=False) if inline else on_sample
        if history_s > 0:
            sub: Any = zenoh.ext.declare_advanced_subscriber(
                self.session, keyexpr, handler,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_age=history_s))
        else:
            sub = self.session.declare_subscriber(keyexpr, handler)
        self._entities.append(sub)
        return sub

    def ring_raw(self, keyexpr: str, capacity: int) -> _Ring:
        # Zenoh's ring channel, filled on its own threads without the GIL: no Python runs per
        # sample (a callback costs a GIL hand-over each, hundreds a second in lockstep).
        sub = self.session.declare_subscriber(keyexpr, zenoh.handlers.RingChannel(capacity))
        self._entities.append(sub)
        return _Ring(sub)

    def queryable_raw(self, key: str, serve: Callable[[bytes | None], bytes],
                      encoding: str = JSON_ENCODING) -> Declared:
        enc = zenoh.Encoding(encoding)

        def on_query(query: zenoh.Query) -> None:
            # ``with``: finalise the query as soon as it is answered. Left to Python's finalizer, it
            # waits for the last reference to go, and a traceback kept by a log handler (a handler
            # bug logged with its stack) holds one: the caller then hears nothing until its timeout.
            with query:
                payload = None if query.payload is None else query.payload.to_bytes()
                query.reply(key, serve(payload), encoding=enc)

        q = self.session.declare_queryable(key, on_query)
        self._entities.append(q)
        return q

    def query_raw(self, selector: str, payload: bytes | None = None, timeout_s: float = 2.0, *,
                  every: bool = False) -> Iterator[RawReply]:
        extra = ({"target": zenoh.QueryTarget.ALL, "consolidation": zenoh.ConsolidationMode.NONE}
                 if every else {})
        return _replies(iter(self.session.get(selector, payload=payload, timeout=timeout_s, **extra)))

    def _declare_token(self, key: str) -> Declared:
        return self.session.liveliness().declare_token(key)

    def _live_tokens(self, selector: str, timeout_s: float) -> Iterator[str]:
        for r in self.session.liveliness().get(selector, timeout=timeout_s):
            if r.ok is not None:
                yield str(r.ok.key_expr)

    def _watch_tokens(self, selector: str, callback: Callable[[str, bool], None]) -> Declared:
        def on_sample(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

        sub = self.session.liveliness().declare_subscriber(selector, on_sample, history=True)
        self._entities.append(sub)
        return sub

    def _close_transport(self) -> None:
        self.session.close()
