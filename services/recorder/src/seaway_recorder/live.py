"""``seaway foxglove``: the running stack, live in Foxglove or Lichtblick (Foxglove WebSocket protocol).

The same channels as a recording (``core.py``): every bus topic of the vessel
(``seaway/<vessel>/...``, the bytes unchanged, ``json`` with its message's JSON Schema), a malformed
sample on ``recorder/malformed``, and the derived Foxglove channels of ``derive.py`` (LocationFix,
GeoJSON, FrameTransform, SceneUpdate on ``foxglove/<vessel>/...``: protobuf, foxglove-sdk's
schemas), served by foxglove-sdk's WebSocket server (``foxglove.start_server``); and the run's log
as ``foxglove.Log`` on ``foxglove/log``, from the lines the recorder tails and puts on the bus
(``logs/line``). Not served: the launcher's events, which only the recorder reads (from the run
folder's ``events.jsonl``).
It only reads the bus: it publishes nothing, answers no request and offers the viewer no way to
send one (no capabilities: no client publish, services or parameters).

Two parts:

* :class:`LiveFeed`, the pure core: one bus sample (key, bytes, encoding, receive time) in, the
  ``(channel, payload, log time)`` to serve out. No Zenoh, no sockets, time passed in.
* :func:`run`, the thin loop: the Zenoh subscription, the :class:`Server`, signals.

A slow viewer never slows the bus. The Zenoh callback only appends the sample to a bounded queue
(``record.SampleQueue``: a full queue drops the sample and counts it, it never blocks), and one
thread drains it into the server. ``Channel.log`` of foxglove-sdk does not wait on a client either:
each client has its own queue of ``--backlog`` messages, the oldest message is dropped when it is
full, and a client whose control queue fills is disconnected (``foxglove.start_server``,
``message_backlog_size``).

Log time follows the recording's real-time convention (``timebase.RecordingTime.real_time``): the
time the sample reached this process; a derived message's own ``timestamp`` is its source's
``stamp_ns`` (sim time from zero in lockstep).

The protocol: foxglove-sdk 0.30 speaks it under the subprotocol name ``foxglove.sdk.v1`` only (the
same messages as ``foxglove.websocket.v1``); Foxglove and Lichtblick releases that offer that name
connect, older ones are refused at the handshake.
"""

from __future__ import annotations

import argparse
import ipaddress
import logging
import sys
import threading
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from seaway.contract import bundle, keys
from seaway.contract.messages import LogRecord, MessageError, PeriodDone
from seaway.recording.timebase import RecordingTime, stamp_of
from seaway.runtime.argtypes import non_negative_float, positive_int, whole_number
from seaway.runtime.service import (
    DEFAULT_VESSEL,
    add_log_level_option,
    add_vessel_option,
    add_zenoh_config_option,
    configure_logging,
    credentials_arg,
    install_stop_signals,
)
from seaway.vessel.frames import GeoOrigin

from seaway_recorder import derive, schemas
from seaway_recorder.node import SampleQueue

log = logging.getLogger("seaway.foxglove")

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
"""Foxglove's own default for a WebSocket connection (``ws://localhost:8765``)."""
DEFAULT_QUEUE = 20_000
"""Samples buffered between Zenoh and the server before drops (a few seconds of a lockstep run)."""
DEFAULT_BACKLOG = 1024
"""Messages buffered per client before its oldest is dropped (foxglove-sdk's own default)."""
SERVER_NAME = "seaway"


@dataclass(frozen=True)
class LiveMessage:
    """One message to serve: its channel (topic, schema, encoding, metadata), bytes, log time (ns)."""

    channel: schemas.ChannelSpec
    payload: bytes
    log_time_ns: int


@dataclass
class LiveStats:
    """What the feed has done: counts per kind and messages per channel."""

    samples: int = 0
    messages: int = 0
    malformed: int = 0
    unregistered: int = 0
    skipped: int = 0
    derived: int = 0
    by_topic: Counter[str] = field(default_factory=Counter)

    def line(self) -> str:
        return (f"samples {self.samples:,}, served {self.messages:,}, derived {self.derived:,}, "
                f"malformed {self.malformed:,}, unregistered {self.unregistered:,}, "
                f"skipped {self.skipped:,}, channels {len(self.by_topic)}")


class LiveFeed:
    """Bus samples in, the recording's channels out, with no file and no Zenoh: what
    ``RecordingWriter.write`` puts in the file, message for message (the same ``schemas`` for the
    bus topics, the same ``derive.FoxgloveDeriver`` and ``timebase.RecordingTime``).

    A registered key's sample is served unchanged on the key's channel once it decodes as the key's
    type; one that does not decode goes to ``recorder/malformed`` in the recorder's envelope; an
    unregistered ``seaway/`` key is served without a schema if it is JSON, skipped (and counted)
    otherwise, since a viewer could not read it. Decoded messages feed the deriver (its channels
    are protobuf with foxglove-sdk's schemas); ``default_origin`` stands until a ``nav/origin``.
    ``time``: the log-time convention (default real time: the receive time).
    """

    def __init__(self, default_origin: GeoOrigin | None = None, time: RecordingTime | None = None) -> None:
        self.stats = LiveStats()
        self.time = time or RecordingTime.real_time()
        self._deriver = derive.FoxgloveDeriver(default_origin, self.time.foxglove_ns)
        self._specs: dict[str, schemas.ChannelSpec] = {}

    def _spec(self, key: str, encoding: str) -> schemas.ChannelSpec:
        spec = self._specs.get(key)
        if spec is None:
            spec = schemas.channel_for_key(key, encoding)
            self._specs[key] = spec
        return spec

    def feed(self, key: str, payload: bytes, encoding: str, receive_ns: int) -> list[LiveMessage]:
        """The messages one sample received at ``receive_ns`` (wall clock) gives: none, its own,
        or its own and the derived ones, each at its log time. A lockstep bundle
        (``seaway.contract.bundle``) gives those of each sample it stands for, as the recording has
        them; one that does not unpack goes to the error channel whole."""
        if encoding != bundle.ENCODING:
            return self._feed_one(key, payload, encoding, receive_ns)
        if bundle.is_resent(payload):  # a copy for a restarted recorder: a viewer has it
            return []
        try:
            parts = bundle.unpack(key, payload)
        except MessageError as err:
            self.stats.samples += 1
            self.stats.malformed += 1
            log_ns = self.time.wall(receive_ns)
            envelope = schemas.malformed_record(key, PeriodDone.SCHEMA, str(err), encoding, payload,
                                                log_ns)
            return self._out([LiveMessage(schemas.malformed_channel(), envelope, log_ns)])
        return [m for k, data, enc in parts for m in self._feed_one(k, data, enc, receive_ns)]

    def _feed_one(self, key: str, payload: bytes, encoding: str, receive_ns: int
                  ) -> list[LiveMessage]:
        self.stats.samples += 1
        spec = self._spec(key, encoding)
        msg: Any = None
        if spec.message_type is None:
            if spec.message_encoding != schemas.JSON:
                self.stats.skipped += 1
                return []
            self.stats.unregistered += 1
        else:
            try:
                msg = spec.message_type.decode(payload)
            except MessageError as err:
                self.stats.malformed += 1
                log_ns = self.time.wall(receive_ns)
                envelope = schemas.malformed_record(key, spec.schema_name, str(err), encoding, payload,
                                                    log_ns)
                return self._out([LiveMessage(schemas.malformed_channel(), envelope, log_ns)])
        stamp = None
        if self.time.lockstep:
            stamp = msg.stamp_ns if msg is not None else stamp_of(payload)
        log_ns = self.time.bus(key, stamp, receive_ns)
        out = [LiveMessage(spec, payload, log_ns)]
        if isinstance(msg, LogRecord):
            # The run's log, as the recorder put it on the bus from the files it tails: the same
            # foxglove.Log the recording has (writer.write_log), at the line's own time.
            line_ns = self.time.wall(msg.stamp_ns)
            d = derive.log_message(line_ns, msg.level, msg.process, msg.logger, msg.message)
            out.append(LiveMessage(derive.channel_spec(d), d.payload(), line_ns))
            self.stats.derived += 1
        elif msg is not None:
            derived = self._deriver.feed(key, msg)
            out += [LiveMessage(derive.channel_spec(d), d.payload(), log_ns) for d in derived]
            self.stats.derived += len(derived)
        return self._out(out)

    def _out(self, out: list[LiveMessage]) -> list[LiveMessage]:
        self.stats.messages += len(out)
        for m in out:
            self.stats.by_topic[m.channel.topic] += 1
        return out


# -- the loop ---------------------------------------------------------------------------------------


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="seaway foxglove",
        description="Serve the running stack to Foxglove or Lichtblick over the Foxglove WebSocket "
                    "protocol, live: every bus topic of the vessel with its JSON Schema and the "
                    "derived Foxglove channels (foxglove.LocationFix for the Map panel), the same "
                    "channels as a recording. Read-only: it publishes nothing on the bus and offers "
                    "the viewer no request. Open ws://HOST:PORT in Foxglove (Open connection -> "
                    "Foxglove WebSocket). Runs on the shore against a boat like any operator "
                    "command (--zenoh-config, --credentials). Ctrl-C stops.")
    add_vessel_option(p, wildcard=True)
    p.add_argument("--host", default=DEFAULT_HOST,
                   help=f"address to serve on (default {DEFAULT_HOST}, this machine only; 0.0.0.0 "
                        "serves every interface: anyone who reaches it sees the bus)")
    p.add_argument("--port", type=whole_number(0, 65535), default=DEFAULT_PORT,
                   help=f"TCP port to serve on (default {DEFAULT_PORT}, Foxglove's default; 0 picks "
                        "a free one, printed at start)")
    p.add_argument("--queue", type=positive_int, default=DEFAULT_QUEUE,
                   help=f"bus samples buffered between Zenoh and the server before new ones are "
                        f"dropped and counted (default {DEFAULT_QUEUE}); the bus never waits")
    p.add_argument("--backlog", type=positive_int, default=DEFAULT_BACKLOG,
                   help=f"messages buffered per viewer before its oldest is dropped (default "
                        f"{DEFAULT_BACKLOG}); a slow viewer loses messages, nobody else does")
    p.add_argument("--status-interval", type=non_negative_float, default=10.0,
                   help="seconds between status lines on stderr (default 10; 0: none)")
    add_zenoh_config_option(p)
    p.add_argument("--credentials", default=None, metavar="DIR",
                   help="the stack's credentials folder, used as identity $SEAWAY_IDENTITY or "
                        "'operator' (default $SEAWAY_CREDENTIALS, else those of the stack on the "
                        "rendezvous port; 'none' runs without authentication)")
    add_log_level_option(p)
    return p


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class Server:
    """foxglove-sdk's WebSocket server and one SDK channel per served topic, created on first use.

    A viewer that subscribes to a channel gets the channel's latest message at once, to it alone
    (``sink_id``): what is published once or rarely (the mission, the hull, the NED frame, the
    origin) is drawn by a viewer that connects later, as a file restores it on a seek. That
    message may arrive just after a newer one sent to every subscriber at the same moment.
    """

    def __init__(self, host: str, port: int, backlog: int) -> None:
        import foxglove
        from foxglove.websocket import ServerListener

        server = self

        class Latest(ServerListener):
            def on_subscribe(self, client: Any, channel: Any) -> None:
                server._send_latest(client.id, channel.topic)

        self._foxglove = foxglove
        self.context = foxglove.Context()
        self._channels: dict[str, Any] = {}
        self._latest: dict[str, tuple[bytes, int]] = {}
        # No capabilities: no client publish, no services, no parameters. The viewer only reads.
        self.ws = foxglove.start_server(name=SERVER_NAME, host=host, port=port, context=self.context,
                                        capabilities=[], message_backlog_size=backlog,
                                        server_listener=Latest())

    @property
    def port(self) -> int:
        return self.ws.port

    def log(self, m: LiveMessage) -> None:
        topic = m.channel.topic
        ch = self._channels.get(topic)
        if ch is None:
            ch = self._channel(m.channel)
            self._channels[topic] = ch
        self._latest[topic] = (m.payload, m.log_time_ns)  # one tuple swapped in: no lock needed
        ch.log(m.payload, log_time=m.log_time_ns)

    def _send_latest(self, client_id: int, topic: str) -> None:
        """On the SDK's thread: the channel's latest message to the one client that subscribed."""
        latest, ch = self._latest.get(topic), self._channels.get(topic)
        if latest is not None and ch is not None:
            ch.log(latest[0], log_time=latest[1], sink_id=client_id)

    def _channel(self, spec: schemas.ChannelSpec) -> Any:
        fg = self._foxglove
        schema = (fg.Schema(name=spec.schema_name, encoding=spec.schema_encoding, data=spec.schema_data)
                  if spec.schema_encoding else None)
        log.info("serving %s (%s)", spec.topic, spec.schema_name or "no schema")
        return fg.Channel(spec.topic, schema=schema, message_encoding=spec.message_encoding,
                          context=self.context, metadata=dict(spec.metadata))

    def stop(self) -> None:
        self.ws.stop()


def _drain(feed: LiveFeed, queue: SampleQueue, server: Server, limit: int) -> int:
    n = 0
    items = queue.items
    while items and n < limit:
        key, payload, encoding, t_ns, _carried = items.popleft()
        queue.out_bytes += len(payload)
        n += 1
        for m in feed.feed(key, payload, encoding, t_ns):
            server.log(m)
    return n


def run(argv: Sequence[str]) -> int:
    from seaway.runtime.bus import Bus

    args = parser().parse_args(list(argv))
    configure_logging("foxglove", args.log_level)
    vessel = args.vessel
    if vessel != "*":
        try:
            keys.check_vessel(vessel)
        except ValueError as err:
            print(f"seaway foxglove: --vessel: {err}", file=sys.stderr)
            return 2
    expr = f"{keys.ROOT}/**" if vessel == "*" else f"{keys.ROOT}/{vessel}/**"
    feed = LiveFeed()
    queue = SampleQueue(args.queue)
    try:
        server = Server(args.host, args.port, args.backlog)
    except RuntimeError as err:  # foxglove-sdk's FoxgloveError: a port in use, an unknown host
        print(f"seaway foxglove: cannot serve on {args.host}:{args.port}: {err} (choose another "
              "--port, or 0 for a free one)", file=sys.stderr)
        return 2
    stop = threading.Event()
    install_stop_signals(stop)
    try:
        try:
            bus = Bus.open(vessel if vessel != "*" else DEFAULT_VESSEL, args.zenoh_config,
                           credentials=credentials_arg(args.credentials))
        except (OSError, ValueError) as err:  # a missing or invalid --zenoh-config
            print(f"seaway foxglove: {err}", file=sys.stderr)
            return 2
        with bus:
            bus.subscribe_raw(expr, queue.on_sample)
            url = f"ws://{args.host}:{server.port}"
            if not _is_loopback(args.host):
                log.warning("serving on %s: anyone who reaches it sees the bus of %s", url, expr)
            print(f"foxglove: serving {expr} on {url} (Foxglove or Lichtblick: Open connection -> "
                  f"Foxglove WebSocket -> {url})", flush=True)
            print("READY", flush=True)
            _loop(feed, queue, server, stop, args.status_interval)
    finally:
        server.stop()
    log.info("stopped: %s; dropped %d", feed.stats.line(), queue.dropped)
    return 0


def _loop(feed: LiveFeed, queue: SampleQueue, server: Server, stop: threading.Event,
          status_s: float) -> None:
    next_status = time.monotonic() + status_s
    while not stop.is_set():
        queue.arrived.clear()
        if _drain(feed, queue, server, limit=2000) == 0:
            queue.arrived.wait(0.05)
        if status_s and time.monotonic() >= next_status:
            log.info("%s; dropped %d; queue %d", feed.stats.line(), queue.dropped, len(queue.items))
            next_status = time.monotonic() + status_s


def main(argv: Sequence[str] | None = None) -> int:
    return run(sys.argv[1:] if argv is None else argv)


if __name__ == "__main__":
    raise SystemExit(main())
