"""The real stack in lockstep (sim, estimator, controller on paper-c1) recorded by the recorder: the
file validates against its schemas and ``seaway report`` agrees with what the controller reported.

The mission is condition #1 flown by NMPC (a copy of the scenario file naming it): 36 s of simulated
time instead of CC-EMPC's 333 s, and every message type the same."""

from __future__ import annotations

import json
import signal
import subprocess

import pytest
from mcap.reader import make_reader
from seaway.contract import keys
from seaway.runtime.bus import Bus

from tests.conftest import BIN, REPO, wait_for
from tests.unit.recorder.foxglove_check import contract_validator, foxglove_messages

pytestmark = pytest.mark.system
SERVICES = ("seaway-sim", "seaway-estimator", "seaway-controller")


@pytest.mark.skipif(not all((BIN / s).exists() for s in SERVICES),
                    reason="sim, estimator and controller are not installed")
def test_lockstep_mission_recorded_and_reported(procs, zenoh_env, tmp_path) -> None:
    scenario = tmp_path / "paper-c1-nmpc.toml"
    text = (REPO / "deploy" / "scenarios" / "paper-c1.toml").read_text()
    assert 'controller = "cc-empc"' in text
    scenario.write_text(text.replace('controller = "cc-empc"', 'controller = "nmpc"')
                        .replace('name = "paper-c1"', 'name = "paper-c1-nmpc"'))
    out = tmp_path / "run"
    rec = procs.start([str(BIN / "seaway"), "record", "--out", str(out), "--scenario", str(scenario)],
                      zenoh_env, "recorder")
    wait_for(lambda: "READY" in procs.log(rec), 20, what="recorder ready")
    statuses = []
    with Bus.open("vessel1") as bus:
        bus.subscribe(keys.MISSION_STATUS, mode="fifo", callback=lambda _k, m: statuses.append(m))
        stack = [procs.start([str(BIN / "seaway-sim"), "--lockstep", "--scenario", str(scenario)],
                             zenoh_env, "sim"),
                 procs.start([str(BIN / "seaway-estimator"), "--lockstep", "--scenario", str(scenario)],
                             zenoh_env, "estimator"),
                 procs.start([str(BIN / "seaway-controller"), "--lockstep", "--scenario", str(scenario)],
                             zenoh_env, "controller")]
        wait_for(lambda: any(s.state == "complete" for s in statuses), 150, interval_s=0.2,
                 what="the mission to complete")
        for p in reversed(stack):
            procs.stop(p, signal.SIGTERM, timeout_s=15)
    procs.stop(rec, signal.SIGTERM, timeout_s=30)
    summary = json.loads(procs.log(rec).strip().splitlines()[-1])
    assert summary["malformed"] == "0" and summary["dropped"] == "0"
    path = out / "recording.mcap"

    # Every recorded message validates against its channel's schema; counts match the summary.
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        stats = reader.get_summary().statistics
        validators = {}
        n = 0
        for schema, channel, m in reader.iter_messages(log_time_order=False):
            n += 1
            if channel.topic.startswith("foxglove/"):  # protobuf, checked by foxglove_messages below
                continue
            assert schema is not None and channel.message_encoding == "json", channel.topic
            v = validators.get(schema.id)
            if v is None:
                v = validators[schema.id] = contract_validator(schema.name, schema.data)
            v.validate(json.loads(m.data))
    assert n == stats.message_count > 1000
    assert foxglove_messages(path), "the derived Foxglove channels, against foxglove-sdk's schemas"

    rep = subprocess.run([str(BIN / "seaway"), "report", str(path), "--out", str(tmp_path / "rep"),
                          "--json"], capture_output=True, text=True, timeout=120)
    assert rep.returncode == 0, rep.stderr
    doc = json.loads(rep.stdout)
    m = doc["metrics"]
    assert m["completed"] and m["legs_completed"] == 2
    # What the controller reported live, from its MissionStatus stream.
    active = min(s.stamp_ns for s in statuses if s.state == "active")
    done = next(s for s in statuses if s.state == "complete")
    assert m["travel_time_s"] == pytest.approx((done.stamp_ns - active) / 1e9, abs=0.1 + 1e-9)
    assert m["energy_j"] == pytest.approx(done.energy_used_j, rel=1e-3)
    assert doc["solve"]["count"] > 0.9 * m["travel_time_s"] / 0.1
