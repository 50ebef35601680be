"""``seaway foxglove``'s pure core (``seaway_recorder.live.LiveFeed``): the recording's channels, live.

The same samples go through the recorder's ``RecordingWriter`` into an MCAP file and through
``LiveFeed``: every channel (topic, schema name, encoding and text, message encoding, metadata) and
every message (bytes, log time) must be the same, derived Foxglove channels and the malformed
envelope included, so a channel the recorder gains and the live view lacks fails here.
"""

from __future__ import annotations

import json
import math
import socket
from pathlib import Path

import pytest
from mcap.reader import make_reader
from seaway.contract import bundle, keys
from seaway.contract.messages import (
    GnssFix,
    NavOrigin,
    PeriodDone,
    SimTruth,
    StateEstimate,
    ThrustCommand,
)
from seaway_recorder import live, schemas
from seaway_recorder.core import RecordingWriter
from seaway_recorder.logtail import log_record, parse_line

from tests.system.foxglove.wsclient import decode_protobuf
from tests.unit.recorder.foxglove_check import contract_validator

V = "v1"
ORIGIN = NavOrigin.make(stamp_ns=0, lat_rad=math.radians(47.0), lon_rad=math.radians(8.0), alt_m=400.0)


def truth(i: int) -> bytes:
    return SimTruth.make(stamp_ns=i * 100_000_000, u_mps=0.5, v_mps=0.0, r_radps=0.0, x_m=1.0 * i,
                         y_m=2.0, psi_rad=0.1, thrust_port_n=1.0, thrust_starboard_n=1.0,
                         energy_j=0.1 * i).encode()


def samples() -> list[tuple[str, bytes, str]]:
    """A short run: positions before and after the origin, a GNSS fix, a command, a malformed sample
    and unregistered keys (JSON and not)."""
    nav = StateEstimate.make(stamp_ns=300_000_000, u_mps=0.5, v_mps=0.0, r_radps=0.0, x_m=3.0, y_m=2.0,
                             psi_rad=0.1).encode()
    gnss = GnssFix.make(stamp_ns=350_000_000, lat_rad=math.radians(47.00001),
                        lon_rad=math.radians(8.00002), alt_m=400.0, fix_type=3,
                        horizontal_std_m=1.5).encode()
    return [
        (keys.SIM_TRUTH.key(V), truth(0), "application/json"),  # no origin yet: no LocationFix
        (keys.NAV_ORIGIN.key(V), ORIGIN.encode(), "application/json"),
        (keys.SIM_TRUTH.key(V), truth(1), "application/json"),
        (keys.SIM_TRUTH.key(V), truth(2), "application/json"),
        (keys.NAV_STATE.key(V), nav, "application/json"),
        (keys.GNSS.key(V), gnss, "application/json"),
        (keys.THRUST.key(V), ThrustCommand.make(stamp_ns=1, thrust_port_n=1.0, thrust_starboard_n=-1.0,
                                                seq=1).encode(), "application/json"),
        (keys.SIM_TRUTH.key(V), b'{"stamp_ns": "soon"}', "application/json"),  # malformed
        (f"{keys.ROOT}/{V}/custom/thing", b'{"a": 1}', "application/json"),  # unregistered, JSON
    ]


def recorded(tmp_path: Path, items: list[tuple[str, bytes, str]]) -> tuple[RecordingWriter, list[tuple]]:
    w = RecordingWriter(tmp_path / "r.mcap")
    w.open(0)
    for i, (key, payload, enc) in enumerate(items):
        w.write(key, payload, enc, 1_000 + i)
    w.close(10_000)
    with open(tmp_path / "r.mcap", "rb") as fh:
        return w, [(c.topic, s.name if s else "", s.encoding if s else "", bytes(s.data) if s else b"",
                    c.message_encoding, dict(c.metadata), bytes(m.data), m.log_time)
                   for s, c, m in make_reader(fh).iter_messages(log_time_order=True)]


def served(items: list[tuple[str, bytes, str]]) -> tuple[live.LiveFeed, list[tuple]]:
    feed = live.LiveFeed()
    out = []
    for i, (key, payload, enc) in enumerate(items):
        for m in feed.feed(key, payload, enc, 1_000 + i):
            c = m.channel
            out.append((c.topic, c.schema_name, c.schema_encoding, c.schema_data, c.message_encoding,
                        dict(c.metadata), m.payload, m.log_time_ns))
    return feed, out


def test_live_channels_and_messages_are_the_recordings(tmp_path: Path) -> None:
    items = samples()
    feed, got = served(items)
    writer, want = recorded(tmp_path, items)
    assert got == want
    topics = {t for t, *_ in got}
    assert {f"foxglove/{V}/sim-truth", f"foxglove/{V}/nav-state", f"foxglove/{V}/sensors-gnss",
            schemas.MALFORMED_TOPIC, f"{keys.ROOT}/{V}/custom/thing"} <= topics
    assert feed.stats.malformed == 1 and feed.stats.unregistered == 1
    assert feed.stats.derived == writer.stats.derived >= 4
    assert feed.stats.messages == len(got)


def test_every_message_reads_with_its_channels_schema() -> None:
    _feed, got = served(samples())
    for topic, name, encoding, data, msg_enc, _meta, payload, _t in got:
        if not name:
            assert topic == f"{keys.ROOT}/{V}/custom/thing" and msg_enc == "json"
        elif encoding == "protobuf":  # a derived Foxglove channel: foxglove-sdk's schema
            assert msg_enc == "protobuf" and name.startswith("foxglove."), topic
            decode_protobuf(name, data, payload)
        else:
            assert encoding == "jsonschema" and msg_enc == "json", topic
            contract_validator(name, data).validate(json.loads(payload))


def test_a_location_fix_is_where_the_vessel_is() -> None:
    _feed, got = served(samples())
    name, data, payload = next((n, d, p) for t, n, _e, d, _m, _md, p, _t in got
                               if t == f"foxglove/{V}/nav-state")
    assert name == "foxglove.LocationFix"
    fix = decode_protobuf(name, data, payload)
    # x = 3 m north, y = 2 m east of 47 N 8 E: 1 deg of latitude is ~111.2 km, of longitude at 47 N
    # ~76.0 km (an independent flat-earth figure; the recorder uses WGS84 through ECEF).
    assert fix["latitude"] == pytest.approx(47.0 + 3.0 / 111_200, abs=2e-7)
    assert fix["longitude"] == pytest.approx(8.0 + 2.0 / 76_000, abs=2e-7)
    assert fix["heading"] == pytest.approx(0.1)
    assert fix["timestamp"] == "1970-01-01T00:00:00.300Z"  # real time: the source's stamp_ns as it is


def test_unreadable_samples_are_skipped_and_counted_not_served() -> None:
    feed = live.LiveFeed()
    assert feed.feed(f"{keys.ROOT}/{V}/custom/blob", b"\x00\x01", "application/octet-stream", 5) == []
    assert feed.stats.skipped == 1 and feed.stats.messages == 0


@pytest.mark.parametrize(("argv", "says"), [
    (["--port", "70000"], "argument --port: '70000' is not a whole number from 0 to 65535"),
    (["--port", "http"], "'http' is not a whole number from 0 to 65535"),
    (["--queue", "0"], "argument --queue: '0' is not a whole number of at least 1"),
    (["--backlog", "many"], "'many' is not a whole number"),
    (["--status-interval", "-1"], "'-1' is not a finite number of at least 0"),
])
def test_bad_options_are_refused_with_what_is_allowed(argv: list[str], says: str,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        live.parser().parse_args(argv)
    assert exc.value.code == 2 and says in capsys.readouterr().err


def test_defaults_serve_this_machine_only_on_foxgloves_port() -> None:
    args = live.parser().parse_args([])
    assert (args.host, args.port) == ("127.0.0.1", 8765)


def test_a_port_in_use_is_refused_with_a_hint(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert live.run(["--port", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"cannot serve on 127.0.0.1:{port}" in err and "Address already in use" in err
    assert "--port" in err


def test_a_log_line_on_the_bus_is_served_as_the_recordings_log(tmp_path: Path) -> None:
    # The recorder tails a process's log: into its file (write_log) and onto the bus (LogRecord);
    # the live feed makes of the bus message the same foxglove.Log, at the same time.
    line = parse_line("2026-11-24 01:02:03,456 controller WARNING seaway_controller.core: slow solve")
    record = log_record("controller", line, now_ns=1)
    assert record.stamp_ns == line.wall_ns and record.level == "WARNING"
    w = RecordingWriter(tmp_path / "r.mcap", foxglove=True)
    w.open(0)
    w.write_log("controller", line)
    w.close(10**19)
    with open(tmp_path / "r.mcap", "rb") as fh:
        (s, _c, m), = make_reader(fh).iter_messages(topics=["foxglove/log"])
    feed = live.LiveFeed()
    got = feed.feed(keys.LOG_LINE.key(V), record.encode(), "application/json", 5)
    assert [g.channel.topic for g in got] == [keys.LOG_LINE.key(V), "foxglove/log"]
    log_msg = got[1]
    assert (log_msg.channel.schema_name, log_msg.channel.schema_data) == (s.name, s.data)
    assert (log_msg.payload, log_msg.log_time_ns) == (bytes(m.data), m.log_time)
    decoded = decode_protobuf(s.name, s.data, log_msg.payload)
    assert decoded["name"] == "controller" and decoded["message"] == "seaway_controller.core: slow solve"
    # A line without a time of its own carries the time it was read.
    assert log_record("sim", parse_line("Traceback (most recent call last):"), now_ns=42).stamp_ns == 42


def test_a_lockstep_bundle_is_served_as_the_samples_it_carries_and_a_bad_one_as_an_error() -> None:
    """``seaway foxglove`` on a lockstep stack: each bundle (seaway.contract.bundle) gives the
    messages of its keys and its answer, as the recording has them; one that does not unpack goes to
    the error channel whole and the feed goes on; a copy sent again for a recorder gives nothing."""
    nav = StateEstimate.make(stamp_ns=100_000_000, u_mps=0.5, v_mps=0.0, r_radps=0.0, x_m=3.0,
                             y_m=2.0, psi_rad=0.1)
    done = PeriodDone(stamp_ns=100_000_000, service="estimator", episode=0, seq=1, period_ns=100_000_000,
                      published={keys.NAV_STATE.suffix: [nav.stamp_ns]})
    key = keys.LOCKSTEP_ESTIMATOR.key(V)
    good = bundle.encode(done.encode(), [(keys.NAV_STATE.suffix, nav.encode())])
    foreign = bundle.encode(done.encode(), [(keys.THRUST.suffix, ThrustCommand.make(
        stamp_ns=1, thrust_port_n=1.0, thrust_starboard_n=1.0, seq=1).encode())])
    resent = bundle.encode(done.model_copy(update={"seq": 2, "resent": True}).encode(),
                           [(keys.NAV_STATE.suffix, nav.encode())])
    feed = live.LiveFeed()
    got = [(m.channel.topic, m.payload) for p in (good, b"{}\nnot a line", foreign, resent, good)
           for m in feed.feed(key, p, bundle.ENCODING, 1_000)]
    topics = [t for t, _ in got]
    assert topics.count(keys.NAV_STATE.key(V)) == 2 and topics.count(key) == 2
    assert (keys.NAV_STATE.key(V), nav.encode()) in got and (key, done.encode()) in got
    assert topics.count(schemas.MALFORMED_TOPIC) == 2 and feed.stats.malformed == 2
    assert keys.THRUST.key(V) not in topics  # the estimator may not carry a command
