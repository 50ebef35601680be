"""What this process's access control refused: counted per identity, action and key, logged once per
source, published and answered on ``seaway/<vessel>/refusals/<identity>``.

Zenoh enforces the stack's access rules (``seaway.contract.access``) inside each receiving process,
with no callback into Python: the one trace a refused message leaves is Zenoh's own log:

* ``zenoh::net::routing::interceptor`` at TRACE, ``Msg intercepted!``: a message dropped (written
  for drops alone). The access-control verdict just before it on the same thread
  (``zenoh::net::routing::interceptor::access_control``: ``<zid> [on ...CertCommonName(<name>)...]
  is unauthorized to Put (ingress) on <key>``) says who, what and where; the certificate's name
  comes with the first verdict on each key a remote uses;
* ``zenoh_link_tls::unicast`` at WARN: a TLS link refused before any identity was proven (no
  certificate, or one from another authority).

So a service routes Zenoh's log (which Zenoh writes to file descriptor 1) through a pipe that it
reads itself (:func:`watch`, before its session opens), counts with :class:`RefusalCounter` (the
pure core), and keeps Python's own ``sys.stdout`` on the real stdout. Zenoh's other log lines reach
stdout only when ``$RUST_LOG`` asks for them, as before.

Cost, and the two levels. Zenoh has no lower level for refusals than TRACE, where it also writes a
line for every message a process sends or receives. In real time (10 Hz) that is nothing; in
lockstep it cost 16 % of each period (``seaway bench lockstep``). So:

* ``full`` (every service in real time; the recorder always): every refusal with its identity,
  action and key. The recorder receives every message published on its vessel, so it sees every
  forged publication there, also in lockstep;
* ``drops`` (the other services in lockstep): only Zenoh's line for a dropped message (``Msg
  intercepted!``, written for drops alone, so free when nothing is refused), counted as identity
  ``unknown`` on action ``refused``: a refused request or token is still counted where it was
  refused, without its name.
"""

from __future__ import annotations

import fcntl
import logging
import os
import re
import select
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from seaway.contract import keys
from seaway.contract import messages as m
from seaway.contract.messages import message_encoding
from seaway.runtime.bus import Bus

log = logging.getLogger("seaway.refusals")

ACL_TARGET = "zenoh::net::routing::interceptor::access_control"
TLS_TARGET = "zenoh_link_tls::unicast"
DROP_TARGET = "zenoh::net::routing::interceptor"
UNAUTHENTICATED = "unauthenticated"
UNKNOWN = "unknown"
LOG_INTERVAL_S = 60.0
"""A source already logged is logged again at most this often, with what it did meanwhile."""
PUBLISH_INTERVAL_S = 1.0
"""A changed report is published at most this often."""
PIPE_BYTES = 1 << 20
"""The log pipe's size (Linux's default limit for an unprivileged process)."""
READ_PAUSE_S = 0.1
"""The reader's pause between reads: at most 10 wake-ups a second."""
ENV_WATCH = "SEAWAY_REFUSALS"
"""``off`` leaves Zenoh's log alone (no counting); for measuring what counting costs."""

_INTERCEPTOR = DROP_TARGET.encode()
# A name is learnt from the verdicts that refuse: every first use of a key by a remote refuses
# some action (a publisher may not reply, for one), and nearly every other line is an allowed message.
_WORDS = (b"unauthorized", b"zenoh_link_tls", b"Msg intercepted!")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_UNAUTHORIZED = re.compile(r"([0-9a-f]{8,})(?: on \S+)? is unauthorized to (.+?) \(ingress\) on (\S+)")
_THREAD = re.compile(r"ThreadId\((\d+)\)")
_NAMED = re.compile(r"([0-9a-f]+) on \S*CertCommonName\(([^)]*)\)")
_ACTIONS = {"Put": "put", "Delete": "delete", "Query": "query", "Reply": "reply",
            "Liveliness Token": "liveliness_token", "Declare/Undeclare Queryable": "declare_queryable",
            "Declare/Undeclare Subscriber": "declare_subscriber",
            "Declare/Undeclare Liveliness Token": "liveliness_token",
            "Declare Liveliness Subscriber": "declare_liveliness_subscriber",
            "Liveliness Query": "liveliness_query"}


@dataclass
class RefusalCounter:
    """The pure core: Zenoh log lines in, counts and log texts out (time passed in, seconds)."""

    identity: str
    names: dict[str, str] = field(default_factory=dict)
    """Zenoh session id (hex) -> certificate common name, learned from the log itself."""
    counts: dict[tuple[str, str, str], list[int]] = field(default_factory=dict)
    """(identity, action, key) -> [count, last_ns]."""
    total: int = 0
    overflow: int = 0
    version: int = 0
    _pending: dict[str, tuple[str, str, str]] = field(default_factory=dict)
    _logged_at: dict[str, float] = field(default_factory=dict)
    _since_log: dict[str, int] = field(default_factory=dict)

    def feed(self, line: str, now_s: float, now_ns: int) -> list[str]:
        """One log line; returns the warnings to log now (rate-limited per source).

        A refusal is Zenoh's ``Msg intercepted!`` line; the access-control verdict just before it on
        the same thread (cached or not: a wildcard subscriber's is never cached) names it.
        """
        thread = _THREAD.search(line)
        where = thread.group(1) if thread else ""
        if ACL_TARGET in line:
            named = _NAMED.search(line)
            if named:
                self.names[named.group(1)] = named.group(2)
            verdict = _UNAUTHORIZED.search(line) if "unauthorized" in line else None
            if verdict:
                zid, action, key = verdict.groups()
                who = self.names.get(zid, f"session {zid}")
                self._pending[where] = (who, _ACTIONS.get(action, action.lower()), key)
            else:
                self._pending.pop(where, None)
            return []
        if "Msg intercepted!" in line:
            return self._count(*self._pending.pop(where, (UNKNOWN, "refused", "")), now_s, now_ns)
        if TLS_TARGET in line and ("WARN" in line or "ERROR" in line):
            return self._count(UNAUTHENTICATED, "connect", "", now_s, now_ns)
        return []

    def _count(self, who: str, action: str, key: str, now_s: float, now_ns: int) -> list[str]:
        self.total += 1
        self.version += 1
        triple = (who, action, key)
        entry = self.counts.get(triple)
        if entry is not None:
            entry[0] += 1
            entry[1] = now_ns
        elif len(self.counts) < m.MAX_REFUSAL_ENTRIES:
            self.counts[triple] = [1, now_ns]
        else:
            self.overflow += 1
        self._since_log[who] = self._since_log.get(who, 0) + 1
        last = self._logged_at.get(who)
        if last is not None and now_s - last < LOG_INTERVAL_S:
            return []
        n = self._since_log.pop(who)
        self._logged_at[who] = now_s
        what = f"{action} on {key}" if key else action
        if last is None:
            return [f"access control refused {who}: {what} (each source is logged once a minute at "
                    "most; `seaway health` shows every count)"]
        return [f"access control refused {who} {n} more times in the last {now_s - last:.0f} s "
                f"(latest: {what})"]

    def report(self, stamp_ns: int) -> m.Refusals:
        counts = [m.RefusalCount(identity=i, action=a, key=k, count=c, last_ns=t)
                  for (i, a, k), (c, t) in sorted(self.counts.items())]
        return m.Refusals(stamp_ns=stamp_ns, identity=self.identity, total=self.total, counts=counts,
                          overflow=self.overflow)


class _Watch:
    """The process-wide reader of Zenoh's log (one per process: Zenoh's log is set up once)."""

    def __init__(self, counter: RefusalCounter, read_fd: int, out_fd: int, forward: bool) -> None:
        self.counter = counter
        self.lock = threading.Lock()
        self.read_fd = read_fd
        self.out_fd = out_fd
        self.forward = forward
        self.listeners: list[Callable[[], None]] = []
        threading.Thread(target=self._run, name="refusals", daemon=True).start()

    def _run(self) -> None:
        rest = b""
        while True:
            ready, _, _ = select.select([self.read_fd], [], [], PUBLISH_INTERVAL_S)
            if ready:
                chunk = os.read(self.read_fd, PIPE_BYTES)
                if not chunk:
                    return
                rest = self._lines(rest + chunk)
                # Wake a few times a second, not per line: a thread that wakes per message takes
                # the interpreter lock from the service's own loop every time, which lengthens
                # every lockstep period. The pipe holds what comes meanwhile.
                time.sleep(READ_PAUSE_S)
            for listener in list(self.listeners):
                try:
                    listener()
                except Exception:  # a bus closing under us must not stop the count
                    log.debug("refusal listener failed", exc_info=True)

    def _lines(self, data: bytes) -> bytes:
        *lines, rest = data.split(b"\n")
        # Nearly every chunk is allowed messages alone: one byte search per word says so, and
        # then no line is looked at (nothing to forward unless $RUST_LOG asked for it).
        if not self.forward and not any(w in data for w in _WORDS):
            return rest
        now_s, now_ns = time.monotonic(), time.time_ns()
        for raw in lines:
            if any(w in raw for w in _WORDS):
                text = _ANSI.sub("", raw.decode(errors="replace"))
                with self.lock:
                    warnings = self.counter.feed(text, now_s, now_ns)
                for w in warnings:
                    log.warning("%s", w)
                continue
            if self.forward and _INTERCEPTOR not in raw:
                os.write(self.out_fd, raw + b"\n")
        return rest


_watch: _Watch | None = None


def watch(identity: str, full: bool = True) -> RefusalCounter | None:
    """Count this process's refusals from here on; call before the process's Zenoh session opens.

    ``full``: with identity, action and key, else drops alone (the module doc says when).

    Returns the counter (the same one on every call), or None when ``$SEAWAY_REFUSALS=off``.
    """
    global _watch
    if _watch is not None:
        return _watch.counter
    if os.environ.get(ENV_WATCH, "").lower() == "off":
        return None
    import zenoh

    user = os.environ.get("RUST_LOG", "")
    # Only the two targets above unless the user asked for more (then theirs reach stdout as before).
    ours = (f"{DROP_TARGET}=trace,{TLS_TARGET}=warn" if full
            else f"{DROP_TARGET}=trace,{ACL_TARGET}=off,{TLS_TARGET}=warn")
    sys.stdout.flush()
    out_fd = os.dup(1)
    read_fd, write_fd = os.pipe()
    try:
        fcntl.fcntl(write_fd, fcntl.F_SETPIPE_SZ, PIPE_BYTES)
    except OSError:  # a lower limit in /proc/sys/fs/pipe-max-size: the default 64 KiB still works
        log.debug("could not enlarge the log pipe", exc_info=True)
    os.dup2(write_fd, 1)
    os.close(write_fd)
    # Python's own prints keep going straight to the real stdout.
    sys.stdout = os.fdopen(out_fd, "w", buffering=1, closefd=False)
    os.environ["RUST_LOG"] = f"{user},{ours}" if user else f"off,{ours}"
    try:
        zenoh.try_init_log_from_env()
    finally:
        if user:
            os.environ["RUST_LOG"] = user
        else:
            del os.environ["RUST_LOG"]
    _watch = _Watch(RefusalCounter(identity), read_fd, out_fd, forward=bool(user))
    return _watch.counter


def serve(bus: Bus, identity: str) -> None:
    """Answer ``refusals/<identity>`` with this process's counts and publish them when they change
    (at most once a second); the recorder records them. No-op when not watching."""
    if _watch is None:
        return
    w = _watch
    key = keys.refusals_key(bus.vessel, identity)

    def current() -> m.Refusals:
        with w.lock:
            return w.counter.report(time.time_ns())

    bus.queryable_raw(key, lambda _payload: current().encode(), message_encoding(m.Refusals))
    pub = bus.raw_publisher(key, message_encoding(m.Refusals))
    sent = [0]

    def on_tick() -> None:
        if bus.closed:
            w.listeners.remove(on_tick)
        elif w.counter.version != sent[0]:
            sent[0] = w.counter.version
            pub.put(current().encode())

    w.listeners.append(on_tick)
