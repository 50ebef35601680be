"""Foxglove-native recordings through the real launcher and processes (#18):

* every message of every JSON channel of a lockstep run validates against the JSON Schema its
  channel carries in the file (``jsonschema`` alone);
* a lockstep run's recording logs every bus message at its sim time on the run's epoch (recorded in
  the file's ``seaway.time`` metadata), and its derived Foxglove messages' own timestamps are the
  same instants;
* every Foxglove channel of it (LocationFix, GeoJSON, FrameTransform, SceneUpdate, Log) decodes,
  byte for byte, against the schema foxglove-sdk ships, and says what the run did;
* (slow) a real-time run of the same scenario spans the same time on its timeline within 2 %.

The scenario is one 30 m leg on the lake boat in calm water (no disturbance, no sensor noise), so
the two runs fly the same mission.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader
from seaway.contract import keys
from seaway.contract.messages import MissionStatus

from tests.unit.recorder.foxglove_check import (
    contract_validator,
    foxglove_messages,
    invalid_messages,
    t_ns,
)

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent
V = "vessel1"
SCENARIO = """\
name = "short"
description = "test: one 30 m leg on the lake boat, calm water, no sensor noise"
seed = 7
vessel = "paper-boat"
dead_zone = true

[origin]
lat_deg = 28.18
lon_deg = 112.94
alt_m = 30.0

[mission]
waypoints_m = [[0.0, 0.0], [30.0, 0.0]]
coa_radius_m = 2.0
task_power_w = 250.0
controller = "cc-empc"
"""


def launch(profile: str, tmp_path: Path, env: dict[str, str], timeout_s: float) -> Path:
    scenario = tmp_path / "short.toml"
    scenario.write_text(SCENARIO)
    run_dir = tmp_path / profile
    out = subprocess.run([str(BIN / "seaway"), "launch", profile, "--scenario", str(scenario),
                          "--run-dir", str(run_dir)], env=env, capture_output=True, text=True,
                         timeout=timeout_s, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    assert "mission complete" in out.stdout, out.stdout[-3000:]
    return run_dir / "recording.mcap"


def time_meta(path: Path) -> dict[str, str]:
    with open(path, "rb") as fh:
        return {m.name: m.metadata for m in make_reader(fh).iter_metadata()}["seaway.time"]


def mission_span_ns(path: Path) -> int:
    """From the first ``active`` to the first ``complete`` mission status, on the file's timeline."""
    times: dict[str, int] = {}
    with open(path, "rb") as fh:
        for _, _, m in make_reader(fh).iter_messages(topics=[keys.MISSION_STATUS.key(V)],
                                                     log_time_order=True):
            times.setdefault(MissionStatus.decode(bytes(m.data)).state, m.log_time)
    return times["complete"] - times["active"]


def test_lockstep_recording_is_on_sim_time_and_every_foxglove_channel_is_valid(tmp_path, zenoh_env):
    t_start_ns = time.time_ns()
    path = launch("sim-batch", tmp_path, zenoh_env, timeout_s=300)
    t_end_ns = time.time_ns()

    # The epoch: when the run started (run.json written), whole seconds, in the file's metadata.
    meta = time_meta(path)
    epoch_ns = int(meta["epoch_ns"])
    assert meta["log_time"] == "sim"
    assert epoch_ns == (path.parent / "run.json").stat().st_mtime_ns // 10**9 * 10**9
    assert t_start_ns - 10**9 <= epoch_ns <= t_end_ns

    # Every bus message is logged at the epoch plus its own sim stamp, exactly; published (received)
    # at the wall time, which in lockstep runs far ahead of it.
    n_bus = n_logs = 0
    last_stamp = 0
    ahead = []
    validators: dict[int, object] = {}
    with open(path, "rb") as fh:
        for schema, channel, m in make_reader(fh).iter_messages(log_time_order=True):
            if channel.message_encoding != "json":
                continue
            doc = json.loads(m.data)
            if schema is not None:
                v = validators.get(schema.id)
                if v is None:
                    v = validators[schema.id] = contract_validator(schema.name, schema.data)
                v.validate(doc)
            if channel.topic == keys.LOG_LINE.key(V):  # a log line: wall-stamped, placed like one
                assert doc["stamp_ns"] > 10**17
                assert epoch_ns <= m.log_time <= epoch_ns + last_stamp + 10**9, doc
                n_logs += 1
            elif channel.topic.startswith(f"seaway/{V}/"):
                assert m.log_time == epoch_ns + doc["stamp_ns"], (channel.topic, m.log_time, doc)
                n_bus += 1
                last_stamp = max(last_stamp, doc["stamp_ns"])
                ahead.append(m.publish_time - m.log_time)
            else:  # the launcher's events: placed on the same timeline, within the run
                assert channel.topic == "launcher/events"
                assert epoch_ns <= m.log_time <= epoch_ns + last_stamp + 10**9
    assert n_bus > 1000
    # Independently of the contract's code: every message of every JSON channel validates against
    # the schema its channel carries in the file (issue #56: optional fields were typed alone while
    # the messages carried null), messages that leave fields unknown among them.
    checked, invalid = invalid_messages(path)
    assert checked > n_bus and invalid == {}, {t: (len(e), e[0]) for t, e in invalid.items()}
    with open(path, "rb") as fh:
        accepted = [json.loads(m.data) for _, _, m in make_reader(fh).iter_messages(
            topics=[keys.MISSION_ACCEPTED.key(V)])]
    assert accepted and "speed_hint_mps" not in accepted[0]
    assert n_logs > 10  # the recorder put the lines it tails on the bus, and recorded them
    assert last_stamp > 20 * 10**9  # a 30 m leg at about 1 m/s
    assert max(ahead) > 0, "publish times are the wall-clock receive times"

    # Every Foxglove channel decodes against foxglove-sdk's own schema (checked in foxglove_messages),
    # its timestamp is its log time, and it shows the run.
    fox = foxglove_messages(path)
    by_name: dict[str, list] = {}
    for topic, name, log_time, msg in fox:
        by_name.setdefault(name, []).append((topic, log_time, msg))
        stamp = getattr(msg, "timestamp", None)
        if stamp is not None and stamp.ByteSize():
            assert t_ns(stamp) == log_time, topic
        assert epoch_ns <= log_time <= epoch_ns + last_stamp + 10**9, topic
    assert {"foxglove.LocationFix", "foxglove.GeoJSON", "foxglove.FrameTransform",
            "foxglove.SceneUpdate", "foxglove.Log"} <= set(by_name)

    fixes = {t for t, _, _ in by_name["foxglove.LocationFix"]}
    assert fixes == {f"foxglove/{V}/{s}" for s in ("sim-truth", "nav-state", "sensors-gnss")}
    state_fixes = [m for t, _, m in by_name["foxglove.LocationFix"] if t.endswith("nav-state")]
    assert state_fixes[-1].position_covariance_type == 3  # KNOWN: from the estimate's covariance
    assert state_fixes[-1].position_covariance[0] > 0 and state_fixes[-1].position_covariance[4] > 0
    last_truth = [m for t, _, m in by_name["foxglove.LocationFix"] if t.endswith("sim-truth")][-1]
    assert last_truth.latitude > 28.18 + 25 / 111_000  # it went about 30 m north
    assert math.isclose(last_truth.longitude, 112.94, abs_tol=1e-6)

    (gj,) = by_name["foxglove.GeoJSON"]
    features = json.loads(gj[2].geojson)["features"]
    assert [f["geometry"]["type"] for f in features] == ["LineString", "Polygon", "Polygon"]

    frames = {(m.parent_frame_id, m.child_frame_id) for _, _, m in by_name["foxglove.FrameTransform"]}
    assert frames == {("map", f"{V}/ned"), (f"{V}/ned", f"{V}/body"), (f"{V}/ned", f"{V}/truth")}
    scenes = {t for t, _, _ in by_name["foxglove.SceneUpdate"]}
    assert scenes == {f"foxglove/{V}/scene/{s}" for s in ("mission", "vessel", "truth", "prediction")}
    predictions = [m for t, _, m in by_name["foxglove.SceneUpdate"] if t.endswith("prediction")]
    assert sum(1 for p in predictions if p.entities and len(p.entities[0].lines[0].points) > 2) > 100

    logs = by_name["foxglove.Log"]
    assert {m.name for _, _, m in logs} >= {"recorder", "sim", "estimator", "controller"}
    assert any("mission" in m.message and m.name == "controller" for _, _, m in logs)


@pytest.mark.slow
def test_real_time_and_lockstep_recordings_of_one_scenario_span_the_same_time(tmp_path, zenoh_env):
    lockstep = launch("sim-batch", tmp_path, zenoh_env, timeout_s=300)
    real = launch("sim", tmp_path, zenoh_env, timeout_s=400)
    assert time_meta(real)["log_time"] == "receive"
    span_lockstep, span_real = mission_span_ns(lockstep), mission_span_ns(real)
    assert span_lockstep > 20 * 10**9
    assert span_real == pytest.approx(span_lockstep, rel=0.02), (span_real / 1e9, span_lockstep / 1e9)
