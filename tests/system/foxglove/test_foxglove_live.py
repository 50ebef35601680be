"""``seaway foxglove`` on a live lockstep stack, as Foxglove sees it (issue 18, item 3).

``seaway foxglove`` (identity ``operator``, as on a shore) is started first, two clients of the
Foxglove WebSocket protocol connect (``wsclient.py``), then ``seaway launch sim-batch`` flies paper
condition #1. The reading client subscribes to every channel as it is advertised and must receive
the bus topics (``nav/state``, ``sim/truth``, ``mission/status``, ...) and the derived
``foxglove.LocationFix`` channels, each advertised with its JSON Schema, every message valid against
it (jsonschema) and the bus topics decoding as their types. The other client subscribes to the
same and then stops reading (a viewer on a slow link): it must lose messages (so it did stall),
while the reading client loses none (``sim/truth`` every period, no gap) and the server drops no
bus sample.
"""

from __future__ import annotations

import itertools
import json
import math
import re
import signal
import socket
import sys
from collections import Counter, defaultdict
from pathlib import Path

import foxglove.messages as fg
import pytest
from seaway.contract import keys

from tests.conftest import BIN, wait_for
from tests.system.foxglove.wsclient import (
    FoxgloveClient,
    Received,
    channel_schema_bytes,
    decode_protobuf,
)
from tests.unit.recorder.foxglove_check import contract_validator

pytestmark = pytest.mark.system
VESSEL = "vessel1"
SCENARIO = "paper-c1"
PERIOD_NS = 100_000_000  # the control period every lockstep topic here is published at (0.1 s)
URL = re.compile(r"^foxglove: serving \S+ on (ws://127\.0\.0\.1:\d+) ", re.MULTILINE)
WANTED = {
    keys.NAV_STATE.key(VESSEL), keys.SIM_TRUTH.key(VESSEL), keys.MISSION_STATUS.key(VESSEL),
    keys.THRUST.key(VESSEL), keys.NAV_ORIGIN.key(VESSEL), keys.GNSS.key(VESSEL),
    f"foxglove/{VESSEL}/sim-truth", f"foxglove/{VESSEL}/nav-state", f"foxglove/{VESSEL}/sensors-gnss",
    f"foxglove/{VESSEL}/tf/body", f"foxglove/{VESSEL}/scene/prediction",
}
"""What the reading client must receive many of: bus topics of every producer and derived channels."""
ONCE = {f"foxglove/{VESSEL}/mission", f"foxglove/{VESSEL}/scene/mission", f"foxglove/{VESSEL}/tf/ned",
        f"foxglove/{VESSEL}/scene/vessel", keys.MISSION_ACCEPTED.key(VESSEL),
        keys.LOG_LINE.key(VESSEL), "foxglove/log"}
"""Published once, before any client could subscribe to them (a channel is advertised with its
first message): they arrive only because a subscriber gets each channel's latest message. The log
(the lines the recorder tails, put on the bus, served as foxglove.Log) comes in bursts."""
BACKLOG = 4096
"""The server's queue per client (``--backlog``): 0.8 s of this run's ~5,000 messages/s."""


def stalled_socket(url: str) -> socket.socket:
    """A TCP connection to the server with a tiny receive buffer: a client that stops reading
    stalls the server's sends to it within a few messages."""
    host, port = url.removeprefix("ws://").split(":")
    s = socket.socket()
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    s.connect((host, int(port)))
    return s


@pytest.mark.slow  # a live real-time stack, about 50 s; test_foxglove_recording runs by default
def test_a_foxglove_client_receives_the_live_stack_with_valid_messages(zenoh_env, procs,
                                                                        tmp_path: Path) -> None:
    fox = procs.start([str(BIN / "seaway"), "foxglove", "--port", "0", "--backlog", str(BACKLOG),
                       "--status-interval", "1"], {**zenoh_env, "SEAWAY_IDENTITY": "operator"}, "foxglove")

    def address() -> re.Match | None:
        if fox.poll() is not None:
            pytest.fail(f"seaway foxglove exited ({fox.returncode}):\n{procs.log(fox)[-3000:]}")
        return URL.search(procs.log(fox))

    url = wait_for(address, 120, what="seaway foxglove's address").group(1)

    reader = FoxgloveClient(url, max_queue=4096)
    staller = FoxgloveClient(url, max_queue=1, sock=stalled_socket(url))
    launcher = procs.start([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", SCENARIO,
                            "--run-dir", str(tmp_path / "run")], zenoh_env, "launcher")

    got: dict[str, list[Received]] = defaultdict(list)
    stall_subscribed = False

    def complete() -> bool:
        """Poll both clients once; True once the mission is reported complete."""
        nonlocal stall_subscribed
        if launcher.poll() is not None and launcher.returncode != 0:
            pytest.fail(f"the launcher failed:\n{procs.log(launcher)[-3000:]}")
        m = reader.poll(0.2)
        reader.subscribe([cid for cid in reader.channels if cid not in reader.subscribed()])
        if not stall_subscribed:  # read until every wanted channel is there, never after that
            staller.poll(0.01)
            if {ch["topic"] for ch in staller.channels.values()} >= WANTED:
                staller.subscribe(list(staller.channels))
                stall_subscribed = True
        if m is None:
            return False
        got[m.channel["topic"]].append(m)
        return (m.channel["topic"] == keys.MISSION_STATUS.key(VESSEL)
                and json.loads(m.data)["state"] == "complete")

    # The whole mission: stack start (a first solver compile takes up to 40 s) plus ~20 s of lockstep.
    wait_for(complete, 600, interval_s=0.0, what="the mission to complete, seen through seaway foxglove")
    assert stall_subscribed, "the stalled client never saw the channels it wanted"
    wait_for(lambda: launcher.poll() is not None, 300, what="the launcher to finish")
    assert launcher.returncode == 0, procs.log(launcher)[-3000:]

    # The server: read-only (no client publish, services or parameters), named.
    assert reader.server_info is not None and reader.server_info["name"] == "seaway"
    assert not {"clientPublish", "services", "parameters"} & set(reader.server_info["capabilities"])

    missing = {t: len(got.get(t, [])) for t in WANTED if len(got.get(t, [])) < 10}
    missing |= {t: 0 for t in ONCE if not got.get(t)}
    assert not missing, f"too few messages on {missing}; received {sorted(got)}"
    nav_origin = json.loads(got[keys.NAV_ORIGIN.key(VESSEL)][0].data)
    lat0, lon0 = math.degrees(nav_origin["lat_rad"]), math.degrees(nav_origin["lon_rad"])
    for topic, msgs in got.items():
        ch = msgs[0].channel
        schema = channel_schema_bytes(ch)
        if topic.startswith(f"{keys.ROOT}/"):  # a bus topic: its bytes, its type's JSON Schema
            spec = keys.spec_for_key(topic)
            assert spec is not None and spec.message is not None, topic
            assert ch["schemaName"] == spec.message.SCHEMA, ch
            assert ch["encoding"] == "json" and ch["schemaEncoding"] == "jsonschema", ch
            validator = contract_validator(ch["schemaName"], schema)
            for m in msgs:
                errors = [e.message for e in validator.iter_errors(json.loads(m.data))]
                assert not errors, f"{topic}: {errors[:3]}"
                spec.message.decode(m.data)
            continue
        # A derived channel: protobuf with foxglove-sdk's schema, read as Foxglove reads it.
        assert topic.startswith(f"foxglove/{VESSEL}/") or topic == "foxglove/log", topic
        assert ch["encoding"] == "protobuf" and ch["schemaEncoding"] == "protobuf", ch
        name = ch["schemaName"]
        assert name.startswith("foxglove."), ch
        docs = [decode_protobuf(name, schema, m.data) for m in msgs]
        if name == "foxglove.LocationFix":
            assert schema == bytes(fg.LocationFix.get_schema().data)
            for doc in docs:  # within 0.001 deg (~100 m) of the origin: paper-c1's path spans 10 m
                assert abs(doc["latitude"] - lat0) < 1e-3 and abs(doc["longitude"] - lon0) < 1e-3, doc
        if name == "foxglove.Log":  # the run's processes, named; the lines as their logs have them
            assert schema == bytes(fg.Log.get_schema().data)
            assert {doc["name"] for doc in docs} <= {"sim", "estimator", "controller", "recorder",
                                                    "launcher"}, docs[:3]
            assert all(doc["message"] for doc in docs), docs[:3]

    # The reading client lost nothing while the other one stalled: sim/truth every period.
    stamps = [json.loads(m.data)["stamp_ns"] for m in got[keys.SIM_TRUTH.key(VESSEL)]]
    gaps = [(a, b) for a, b in itertools.pairwise(stamps) if b - a not in (0, PERIOD_NS)]
    assert not gaps, f"the reading client missed sim/truth periods: {gaps[:5]} of {len(stamps)}"
    assert len(stamps) > 2000, len(stamps)  # ~3,330 periods in paper-c1

    # The stalled client did stall: what it can still read (its backlog, the sockets' buffers) is
    # far less than what the reader got on the same channels.
    stalled = Counter(m.channel["topic"] for m in staller.drain(quiet_s=3.0))
    topics = {ch["topic"] for ch in staller.channels.values() if ch["id"] in staller.subscribed()}
    sent = sum(len(got[t]) for t in topics)
    assert sent > 20_000 and sum(stalled.values()) < 0.8 * sent, (sent, dict(stalled))
    reader.close()
    staller.close()

    procs.stop(fox, signal.SIGTERM, timeout_s=60)
    assert fox.returncode == 0, procs.log(fox)[-3000:]
    last = re.findall(r"stopped: samples ([\d,]+), .*; dropped (\d+)", procs.log(fox))
    assert last and int(last[-1][0].replace(",", "")) > 20_000 and last[-1][1] == "0", \
        procs.log(fox)[-2000:]
    print(f"reader: {sum(len(v) for v in got.values())} messages on {len(got)} channels; stalled "
          f"client: {dict(stalled)}; server: {last[-1]}", file=sys.stderr)
