"""Recorder, report and replay with real processes: a known mission recorded, read back, measured."""

from __future__ import annotations

import base64
import json
import math
import signal
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from tests.conftest import BIN, wait_for
from tests.system.recorder import mission_publisher as mp
from tests.unit.recorder.foxglove_check import contract_validator, foxglove_messages

pytestmark = pytest.mark.system
HERE = Path(__file__).parent
PUBLISHER = str(HERE / "mission_publisher.py")



def json_lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.startswith("{")]


def record_mission(procs, env, out: Path, malformed: int = 0, extra: list[str] = ()) -> tuple[dict, dict]:
    """Recorder + mission publisher; returns (publisher summary, recorder summary)."""
    rec = procs.start([str(BIN / "seaway"), "record", "--out", str(out), "--scenario", "paper-c1",
                       "--meta", "test=recorder-mission",
                       "--status-interval", str(mp.STATUS_INTERVAL_S), *extra], env, "recorder")
    wait_for(lambda: "READY" in procs.log(rec), 20, what="recorder ready")
    pub = procs.start([sys.executable, PUBLISHER, "--malformed", str(malformed)], env, "publisher")
    assert pub.wait(60) == 0, procs.log(pub)
    sent = json_lines(procs.log(pub))[-1]
    mp.stop_when_written(procs, rec, sent["sent"] + malformed)
    assert rec.returncode == 0, procs.log(rec)
    return sent, json_lines(procs.log(rec))[-1]


def independent_metrics(msgs: list[tuple[str, bytes]], live: dict) -> dict:
    """The paper's metrics computed here, from the published truth, with numpy (not the recorder's code)."""
    truth = [json.loads(d) for k, d in msgs if k.endswith("/sim/truth")]
    t = np.array([m["stamp_ns"] for m in truth], dtype=np.int64)
    x = np.array([m["x_m"] for m in truth])
    y = np.array([m["y_m"] for m in truth])
    e = np.array([m["energy_j"] for m in truth])
    wp = np.array(mp.WAYPOINTS)
    i0 = int(np.searchsorted(t, live["mission_start_ns"]))
    # Leg of each sample: walk the circles in order.
    leg = np.ones(len(t), dtype=int)
    active, end = 1, None
    for i in range(i0, len(t)):
        while active < len(wp) and np.hypot(x[i] - wp[active, 0], y[i] - wp[active, 1]) <= mp.COA_M:
            active += 1
        leg[i] = min(active, len(wp) - 1)
        if active == len(wp):
            end = i
            break
    assert end is not None
    sl = slice(i0, end + 1)
    a, b = wp[leg[sl] - 1], wp[leg[sl]]
    d = b - a
    xte = np.abs(d[:, 0] * (y[sl] - a[:, 1]) - d[:, 1] * (x[sl] - a[:, 0])) / np.hypot(d[:, 0], d[:, 1])
    dist = np.hypot(x[sl, None] - wp[None, :, 0], y[sl, None] - wp[None, :, 1])
    outside = (dist > mp.COA_M).all(axis=1)
    travel = (t[end] - t[i0]) / 1e9
    return {"travel_time_s": travel, "energy_j": e[end] - e[i0] + mp.TASK_POWER_W * travel,
            "avg_cross_track_m": float(xte[outside].mean()), "max_cross_track_m": float(xte[outside].max()),
            "samples": int(outside.sum())}


def test_mission_recorded_read_back_validated_and_reported(procs, zenoh_env, tmp_path) -> None:
    out = tmp_path / "run"
    sent, summary = record_mission(procs, zenoh_env, out, malformed=3)
    path = out / "recording.mcap"
    assert summary["files"] == [str(path)]
    msgs, live = mp.generate()
    assert sent["sent"] == len(msgs)

    # Every message is in the file, bytes unchanged, in order per key; the malformed ones are counted
    # and kept on the error channel with their bytes.
    assert int(summary["malformed"]) == 3 and int(summary["dropped"]) == 0
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summ = reader.get_summary()
        assert summ.statistics is not None and summ.chunk_indexes, "fully indexed file"
        assert all(ci.message_index_offsets for ci in summ.chunk_indexes)
        got: dict[str, list[bytes]] = {}
        malformed = []
        validators: dict[int, object] = {}
        for schema, channel, m in reader.iter_messages(log_time_order=False):
            if channel.topic.startswith("foxglove/"):  # protobuf, foxglove-sdk's schemas: below
                assert channel.message_encoding == "protobuf"
                continue
            # Every message, the error channel's included, validates against its channel's JSON Schema.
            assert schema is not None and schema.encoding == "jsonschema", channel.topic
            assert channel.message_encoding == "json"
            validator = validators.get(schema.id)
            if validator is None:
                validator = validators[schema.id] = contract_validator(schema.name, schema.data)
            validator.validate(json.loads(m.data))
            if channel.topic == "recorder/malformed":
                malformed.append(json.loads(m.data))
                continue
            got.setdefault(channel.topic, []).append(bytes(m.data))
        attachments = {a.name for a in reader.iter_attachments()}
        metadata = {md.name: md.metadata for md in reader.iter_metadata()}
    expected: dict[str, list[bytes]] = {}
    for k, d in msgs:
        expected.setdefault(k, []).append(d)
    assert got == expected
    assert sorted(bytes(base64.b64decode(r["payload_base64"])) for r in malformed) == \
        sorted(p for _, p in mp.MALFORMED)
    assert {r["key"].rsplit("/", 2)[-2] + "/" + r["key"].rsplit("/", 1)[-1] for r in malformed} == \
        {s for s, _ in mp.MALFORMED}
    # Foxglove's map: truth, state and GNSS positions as LocationFix (foxglove-sdk's schema), at the
    # right place.
    foxglove = [(t, d) for t, name, _, d in foxglove_messages(path) if name == "foxglove.LocationFix"]
    topics = {t for t, _ in foxglove}
    assert topics == {f"foxglove/vessel1/{s}" for s in ("sim-truth", "nav-state", "sensors-gnss")}
    first_truth = next(d for t, d in foxglove if t.endswith("sim-truth"))
    assert math.isclose(first_truth.latitude, 47.0, abs_tol=1e-9)
    assert math.isclose(first_truth.longitude, 8.0, abs_tol=1e-9)
    # The run can be rebuilt from the file alone.
    assert {"scenario/paper-c1.toml", "vessel/paper-sim.toml"} <= attachments
    assert metadata["seaway.run"]["scenario"] == "paper-c1"
    assert metadata["seaway.run"]["test"] == "recorder-mission"
    assert metadata["seaway.recorder.summary"]["malformed"] == "3"

    # The report's metrics match the independent computation and the live (controller) figure.
    import subprocess

    rep = subprocess.run([str(BIN / "seaway"), "report", str(path), "--out", str(tmp_path / "rep")],
                         capture_output=True, text=True, timeout=120, env=zenoh_env)
    assert rep.returncode == 0, rep.stderr
    assert "travel time" in rep.stdout and "avg cross-track error" in rep.stdout
    doc = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    m = doc["metrics"]
    ind = independent_metrics(msgs, live)
    assert m["completed"] is True
    assert m["travel_time_s"] == pytest.approx(ind["travel_time_s"], abs=1e-9)
    assert m["travel_time_s"] == pytest.approx(live["travel_time_s"], abs=1e-9)
    assert m["energy_j"] == pytest.approx(ind["energy_j"], rel=1e-9)
    assert m["energy_j"] == pytest.approx(live["energy_j"], rel=1e-9)
    assert doc["controller_reported"]["energy_used_j"] == pytest.approx(live["energy_j"], rel=1e-9)
    # A recording made without mission/energy (before the budget existed) says so and still works.
    assert doc["energy_budget"] == {"recorded": False, "note": "no energy budget recorded"}
    assert "no energy budget recorded" in rep.stdout
    # The zero-order-hold thrust integral agrees with the sim's energy integral.
    assert m["energy_check_j"] == pytest.approx(m["energy_j"], rel=1e-9)
    assert m["avg_cross_track_m"] == pytest.approx(ind["avg_cross_track_m"], rel=1e-9)
    assert m["max_cross_track_m"] == pytest.approx(ind["max_cross_track_m"], rel=1e-9)
    assert m["cross_track_samples"] == ind["samples"]
    assert m["avg_cross_track_m"] > 0.05  # the drift makes the error non-trivial
    s = doc["solve"]
    n_active = sum(1 for k, _ in msgs if k.endswith("/ctrl/solve"))
    assert s["count"] == n_active and s["failures"] == len(mp.FAILED_SOLVES)
    assert s["fallback_levels"] == {"2": len(mp.FAILED_SOLVES)}
    times = sorted(json.loads(d)["solve_time_s"] * 1e3 for k, d in msgs if k.endswith("/ctrl/solve"))
    assert s["solve_time_max_ms"] == pytest.approx(times[-1])
    assert s["solve_time_median_ms"] == pytest.approx(float(np.median(times)))
    for png in ("trajectory.png", "thrust.png", "cross_track.png", "energy.png"):
        data = (tmp_path / "rep" / png).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000, png

    # Without truth (nav/state + ctrl/thrust only, alpha from the attached vessel file) the report
    # still works, from the estimate and the commands.
    rep2 = subprocess.run([str(BIN / "seaway"), "report", str(path), "--out", str(tmp_path / "rep2"),
                           "--no-plots", "--json", "--state", "nav/state"],
                          capture_output=True, text=True, timeout=120)
    assert rep2.returncode == 0, rep2.stderr
    m2 = json.loads(rep2.stdout)["metrics"]
    assert m2["state_source"] == "nav/state" and m2["completed"]
    assert m2["energy_source"].startswith("ctrl/thrust") and doc["alpha_w_per_n2"] == mp.ALPHA
    # nav/state is offset by 1 cm here, so the circle may be entered one sample apart.
    assert abs(m2["travel_time_s"] - ind["travel_time_s"]) <= 0.1 + 1e-9
    one_sample_j = 0.1 * (2 * mp.ALPHA * 3.5**2 + mp.TASK_POWER_W)  # thrusts stay below 3.5 N
    assert m2["energy_j"] == pytest.approx(ind["energy_j"], abs=one_sample_j)


def recorded_bus_messages(path: Path) -> dict[str, list[bytes]]:
    with open(path, "rb") as fh:
        out: dict[str, list[bytes]] = {}
        for _, channel, m in make_reader(fh).iter_messages(log_time_order=True):
            if channel.topic.startswith("seaway/"):
                out.setdefault(channel.topic, []).append(bytes(m.data))
    return out


def log_span_s(path: Path, topic: str) -> float:
    with open(path, "rb") as fh:
        times = [m.log_time for _, _, m in make_reader(fh).iter_messages(topics=[topic])]
    return (times[-1] - times[0]) / 1e9


def test_replay_republishes_paced_and_filtered(procs, zenoh_env, tmp_path) -> None:
    import subprocess

    # A recording with a known pace: the publisher spaces its messages by about 1 ms.
    src = tmp_path / "src.mcap"
    rec = procs.start([str(BIN / "seaway"), "record", "--out", str(src)], zenoh_env, "rec-src")
    wait_for(lambda: "READY" in procs.log(rec), 20, what="recorder ready")
    pub = procs.start([sys.executable, PUBLISHER, "--pace", "0.001"], zenoh_env, "publisher")
    assert pub.wait(60) == 0, procs.log(pub)
    procs.stop(rec, signal.SIGTERM, timeout_s=20)
    original = recorded_bus_messages(src)
    span = log_span_s(src, "seaway/vessel1/nav/state")
    assert span > 1.5

    def replay_into(name: str, *args: str) -> tuple[dict, Path]:
        out = tmp_path / f"{name}.mcap"
        r2 = procs.start([str(BIN / "seaway"), "record", "--out", str(out)], zenoh_env, f"rec-{name}")
        wait_for(lambda: "READY" in procs.log(r2), 20, what="recorder ready")
        rp = subprocess.run([str(BIN / "seaway"), "replay", str(src), "--wait", "0.5", *args],
                            capture_output=True, text=True, timeout=120, env=zenoh_env)
        assert rp.returncode == 0, rp.stderr
        procs.stop(r2, signal.SIGTERM, timeout_s=20)
        return json.loads(rp.stdout.strip().splitlines()[-1]), out

    # As fast as possible, leaving nav/state to a "live estimator": everything else comes back
    # byte for byte and in order; nav/state does not.
    stats, fast = replay_into("fast", "--fast", "--exclude", "nav/state")
    got = recorded_bus_messages(fast)
    assert got == {k: v for k, v in original.items() if not k.endswith("/nav/state")}
    assert stats["elapsed_s"] < span / 2
    assert stats["published"] == sum(len(v) for v in got.values())

    # At twice the original pace, only the states (a live controller makes the rest).
    stats, paced = replay_into("paced", "--rate", "2", "--only", "seaway/*/nav/state")
    got = recorded_bus_messages(paced)
    assert got == {k: v for k, v in original.items() if k.endswith("/nav/state")}
    assert stats["elapsed_s"] == pytest.approx(span / 2, rel=0.15, abs=0.05)
    assert log_span_s(paced, "seaway/vessel1/nav/state") == pytest.approx(span / 2, rel=0.15, abs=0.05)
