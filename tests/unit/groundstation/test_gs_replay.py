"""Replay in the page: a recording cut into the live stream's frames, the runs folder (names that
stay inside it), uploads (bounded, MCAP only), and the API over them, with recordings written by
the recorder's own writer into a temporary runs folder."""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from seaway.contract import keys
from seaway.contract.messages import (
    MissionRequest,
    MissionStatus,
    NavOrigin,
    SolveRecord,
    StateEstimate,
    ThrustCommand,
    Waypoint,
)
from seaway.runtime.memory_bus import MemoryHub
from seaway_groundstation import replay
from seaway_groundstation.app import create_app
from seaway_groundstation.fleet import Fleet
from seaway_groundstation.journal import RequestJournal
from seaway_groundstation.recordings import RecordingError, RunsFolder
from seaway_groundstation.settings import Settings
from seaway_recorder.core import RecordingWriter

TOKEN = "test-token-0123456789abcdef"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
V = "boat7"
T0 = 1_700_000_000_000_000_000
PERIOD_NS = 100_000_000
ORIGIN = NavOrigin(stamp_ns=T0, lat_rad=math.radians(28.18), lon_rad=math.radians(112.94), alt_m=30.0)


def state(i: int) -> StateEstimate:
    return StateEstimate(stamp_ns=T0 + i * PERIOD_NS, u_mps=1.0, v_mps=0.0, r_radps=0.0,
                         x_m=0.1 * i, y_m=0.5, psi_rad=0.0, tau_d_surge_n=0.2)


def write_run(folder: Path, n: int = 50, mission_id: str = "m1", **writer: Any) -> Path:
    """A run folder with one recording of ``n`` control periods of one vessel flying north."""
    folder.mkdir(parents=True, exist_ok=True)
    w = RecordingWriter(folder / "recording.mcap", foxglove=False, **writer)
    w.open(T0)

    def put(spec: keys.KeySpec, msg: Any, at_ns: int) -> None:
        assert w.write(spec.key(V), msg.encode(), f"application/json;{msg.SCHEMA}", at_ns)

    put(keys.NAV_ORIGIN, ORIGIN, T0)
    for i in range(n):
        t = T0 + i * PERIOD_NS
        put(keys.NAV_STATE, state(i), t + 1_000_000)
        put(keys.THRUST, ThrustCommand(stamp_ns=t, thrust_port_n=10.0, thrust_starboard_n=10.0),
            t + 2_000_000)
        put(keys.SOLVE, SolveRecord(stamp_ns=t, controller="cc-empc", status="ok", success=True,
                                    iterations=1, solve_time_s=1e-4, predicted_x_m=[0.1 * i, 0.1 * i + 1],
                                    predicted_y_m=[0.5, 0.5]), t + 3_000_000)
        put(keys.MISSION_STATUS, MissionStatus(stamp_ns=t, state="active", mission_id=mission_id,
                                               active_leg=1, waypoint_count=2, cross_track_m=0.5,
                                               energy_used_j=float(i)), t + 4_000_000)
    w.close(T0 + n * PERIOD_NS)
    return folder


@pytest.fixture
def runs(tmp_path: Path) -> Path:
    return tmp_path / "runs"


@pytest.fixture
def client(runs: Path, tmp_path: Path) -> Iterator[TestClient]:
    hub = MemoryHub()
    settings = Settings(token=TOKEN, runs_dir=runs, upload_dir=tmp_path / "uploads", max_upload_bytes=200_000)
    with TestClient(create_app(hub.bus("gs"), settings)) as c:
        yield c


# -- frames --------------------------------------------------------------------------------------


def test_frames_are_the_live_streams_frames_latest_only_at_its_rate() -> None:
    msgs = [(T0 + i * 10_000_000, V, "state", state(i)) for i in range(40)]  # 100 Hz for 0.4 s
    frames = replay.cut_frames(msgs, T0, rate_hz=20.0, stale_after_s=2.0)
    assert [f.t_s for f in frames] == pytest.approx([0.05 * k for k in range(1, 9)])
    # Each frame carries the latest state of its period, never a backlog: the one live would send.
    xs = [json.loads(f.frame)["updates"]["state"]["message"]["x_m"] for f in frames]
    assert xs == pytest.approx([0.1 * (5 * k - 1) for k in range(1, 9)])
    live = Fleet(2.0)
    for t_ns, v, kind, m in msgs[:5]:
        live.on_message(v, kind, m, (t_ns - T0) / 1e9)
    assert live.changes({}, None, 0.05) == [frames[0].frame]
    text, count = replay.window(frames, 0.1, 0.25)
    assert count == 3 and [f["t_s"] for f in json.loads(text)] == pytest.approx([0.1, 0.15, 0.2])


def test_a_gap_in_the_recording_shows_as_stale() -> None:
    msgs = [(T0, V, "state", state(0)), (T0 + 5_000_000_000, V, "mission",
                                          MissionStatus(stamp_ns=1, state="active"))]
    frames = replay.cut_frames(msgs, T0, rate_hz=20.0, stale_after_s=2.0)
    assert len(frames) == 2  # no frames for the empty periods between
    last = json.loads(frames[-1].frame)
    assert "state" not in last["updates"]  # nothing new on it ...
    fleet_view = json.loads(frames[0].frame)["updates"]["state"]
    assert not fleet_view["stale"]


def test_only_the_last_message_of_a_kind_per_frame_is_decoded() -> None:
    raw = [(T0 + i * 10_000_000, state(i).encode()) for i in range(40)]  # 100 Hz for 0.4 s
    raw[24] = (raw[24][0], b'{"not": "a state"}')  # the last of the fifth period does not decode
    decoded: list[bytes] = []

    def decode(kind: str, data: bytes) -> StateEstimate | None:
        decoded.append(data)
        try:
            return StateEstimate.decode(data)
        except Exception:
            return None

    cutter = replay.Cutter(T0, 20.0, 2.0, decode)
    frames = [f for t, data in raw for f in cutter.add(t, V, "state", data)] + cutter.finish()
    assert len(frames) == 8 and len(decoded) == 9  # one a frame, and one more where the last is bad
    assert cutter.undecodable == 1
    xs = [json.loads(f.frame)["updates"]["state"]["message"]["x_m"] for f in frames]
    expected = [0.1 * (5 * k - 1) for k in range(1, 9)]
    expected[4] = 2.3  # the fifth period's last state does not decode: the one before it
    assert xs == pytest.approx(expected)
    whole = replay.cut_frames([(t, V, "state", state(i)) for i, (t, _) in enumerate(raw) if i != 24],
                              T0, 20.0, 2.0)
    assert [f.frame for f in frames] == [f.frame for f in whole]


def test_a_timeline_answers_only_for_the_frames_it_has_cut(runs: Path) -> None:
    from seaway.recording import reader
    from seaway_groundstation.timeline import Timeline

    write_run(runs / "r1", n=50, chunk_size=2048)
    files = reader.open_paths([runs / "r1"])
    info = reader.read_info(files)
    tl = Timeline(files, info.summaries, info.start_ns, 20.0, 2.0)
    assert tl.window(0.0, 10.0, 1 << 20) == (b"[]", 0, 0.0) and not tl.complete  # nothing read yet
    tl.start().wait(10.0, 30.0)
    text, count, upto = tl.window(0.0, 10.0, 1 << 20)
    assert tl.complete and upto == 10.0 and count == len(json.loads(text)) > 40
    assert [f["frame"] for f in json.loads(text)] == [json.loads(f.frame) for f in _whole_cut(files, info)]


def _whole_cut(files: list[Path], info: Any) -> list[replay.ReplayFrame]:
    """The frames as cut from every message decoded first (the way it was done before)."""
    import heapq

    from seaway.recording import reader
    from seaway_groundstation.gateway import TOPICS

    dec = reader.decode_vessel(files, V, [s.suffix for s in TOPICS.values()], info.summaries)
    streams = [[(t, V, kind, m) for t, m in zip(dec.log_ns.get(spec.suffix, []), dec.get(spec.suffix),
                                                strict=True)] for kind, spec in TOPICS.items()]
    return replay.cut_frames(heapq.merge(*streams, key=lambda s: s[0]), info.start_ns, 20.0, 2.0)


# -- the runs folder -----------------------------------------------------------------------------


def test_listing_and_names_that_leave_the_folder(runs: Path, tmp_path: Path) -> None:
    write_run(runs / "20260101-sim-lake")
    write_run(runs / "study" / "run-a", n=5)
    (runs / "20260101-sim-lake" / "report").mkdir()
    (runs / "20260101-sim-lake" / "report" / "metrics.json").write_text("{}")
    outside = write_run(tmp_path / "secret")
    os.symlink(outside, runs / "link-out")
    folder = RunsFolder(runs)
    entries = {e.id: e for e in folder.entries()}
    assert set(entries) == {"20260101-sim-lake", "study/run-a"}  # the symlink out is not listed
    assert entries["20260101-sim-lake"].has_report and not entries["study/run-a"].has_report
    assert folder.resolve("study/run-a")[1][0].name == "recording.mcap"
    for bad in ("../secret", "/etc/passwd", "study/../../secret", "link-out", "a\\b", "", "./x", "x//y"):
        with pytest.raises(RecordingError) as err:
            folder.resolve(bad)
        assert err.value.status == 422, bad
    with pytest.raises(RecordingError) as err:
        folder.resolve("no-such-run")
    assert err.value.status == 404 and "no-such-run" in err.value.detail


# -- the API -------------------------------------------------------------------------------------


def test_open_a_run_and_read_its_frames_missions_origin_and_report(client: TestClient, runs: Path) -> None:
    run = write_run(runs / "r1", n=50, mission_id="from-gs")
    mission = MissionRequest(stamp_ns=T0, mission_id="from-gs", coa_radius_m=1.5, task_power_w=10.0,
                             waypoints=[Waypoint(x_m=0.0, y_m=0.5), Waypoint(x_m=20.0, y_m=0.5)])
    RequestJournal(run).record(V, keys.MISSION_SET.suffix, "accepted", "ok", mission.model_dump(mode="json"))
    (run / "report").mkdir()
    (run / "report" / "metrics.json").write_text(json.dumps({"metrics": {"energy_j": 12.5}}))
    listed = client.get("/api/recordings").json()
    assert [r["id"] for r in listed["recordings"]] == ["r1"] and listed["recordings"][0]["has_report"]

    d = client.get("/api/recording", params={"id": "r1"}).json()
    assert d["vessels"] == [V] and d["duration_s"] == pytest.approx(4.904, abs=1e-3)
    assert d["report"] == {"metrics": {"energy_j": 12.5}}
    (plan,) = d["missions"]
    assert plan["mission_id"] == "from-gs" and plan["source"] == "groundstation"
    assert plan["waypoints_m"] == [[0.0, 0.5], [20.0, 0.5]] and plan["coa_radius_m"] == 1.5
    assert d["geo"][V]["lat0_deg"] == pytest.approx(28.18)

    w = client.get("/api/recording/frames", params={"id": "r1", "start_s": 0, "end_s": 100}).json()
    d = client.get("/api/recording", params={"id": "r1"}).json()  # every frame is cut by now
    assert w["complete"] and d["complete"] and w["loaded_to_s"] == 100
    assert w["count"] == d["frame_count"] == len(w["frames"]) > 40
    kinds = {k for f in w["frames"] for k in f["frame"]["updates"]}
    assert kinds == {"origin", "state", "thrust", "solve", "mission"}
    last_state = [f["frame"]["updates"]["state"] for f in w["frames"] if "state" in f["frame"]["updates"]][-1]
    assert last_state["message"]["x_m"] == pytest.approx(4.9) and not last_state["stale"]
    part = client.get("/api/recording/frames", params={"id": "r1", "start_s": 1, "end_s": 2}).json()
    assert part["frames"] and all(1 <= f["t_s"] < 2 for f in part["frames"])
    backwards = client.get("/api/recording/frames", params={"id": "r1", "start_s": 2, "end_s": 1})
    assert backwards.status_code == 422


def test_frames_of_a_growing_recording_come_from_the_state_it_was_opened_in(
        client: TestClient, runs: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A recording still being written was opened (repaired, read) again for every frames request
    as it grew: a 40 MB live run loaded a few per cent a minute. Its frames now come from the state
    the page opened; opening it again reads the new state."""
    monkeypatch.setenv("SEAWAY_REPAIR_DIR", str(tmp_path / "repairs"))
    (runs / "live").mkdir(parents=True)
    w = RecordingWriter(runs / "live" / "recording.mcap", foxglove=False, chunk_size=2048)
    w.open(T0)

    def record(periods: range) -> None:
        for i in periods:
            assert w.write(keys.NAV_STATE.key(V), state(i).encode(),
                           f"application/json;{StateEstimate.SCHEMA}", T0 + i * PERIOD_NS)
        w.flush()

    record(range(50))
    opened = client.get("/api/recording", params={"id": "live"}).json()
    for k in range(1, 4):
        record(range(50 * k, 50 * (k + 1)))
        r = client.get("/api/recording/frames", params={"id": "live", "start_s": 0, "end_s": 100}).json()
        assert r["complete"] and r["duration_s"] == opened["duration_s"]
    assert len(list((tmp_path / "repairs").glob("*/*.recovered.mcap"))) == 1
    again = client.get("/api/recording", params={"id": "live"}).json()
    assert again["duration_s"] > opened["duration_s"] + 10
    w.close(T0 + 200 * PERIOD_NS)


def test_bad_names_and_missing_recordings_are_refused_clearly(client: TestClient, runs: Path) -> None:
    write_run(runs / "r1", n=3)
    r = client.get("/api/recording", params={"id": "../../etc"})
    assert r.status_code == 422 and "'..'" in r.json()["detail"]
    assert client.get("/api/recording", params={"id": "nope"}).status_code == 404
    assert client.get("/api/recording", params={"id": "upload:zz"}).status_code == 422
    (runs / "broken").mkdir()
    (runs / "broken" / "recording.mcap").write_bytes(b"\x89MCAP0\r\n" + b"garbage" * 10)
    r = client.get("/api/recording", params={"id": "broken"})
    assert r.status_code == 422 and "broken" in r.json()["detail"]


def test_uploads_need_the_token_are_bounded_and_must_be_mcap(client: TestClient, tmp_path: Path) -> None:
    data = (write_run(tmp_path / "src", n=20) / "recording.mcap").read_bytes()
    raw = {"Content-Type": "application/octet-stream"}
    assert client.post("/api/recordings/upload?name=a.mcap", content=data, headers=raw).status_code == 401
    assert client.post("/api/recordings/upload?name=a.mcap", content=data,
                       headers={**AUTH, "Content-Type": "text/plain"}).status_code == 415
    r = client.post("/api/recordings/upload?name=a.txt", content=data, headers={**AUTH, **raw})
    assert r.status_code == 422 and ".mcap" in r.json()["detail"]
    r = client.post("/api/recordings/upload?name=a.mcap", content=b"not an mcap at all",
                    headers={**AUTH, **raw})
    assert r.status_code == 422 and "not an MCAP file" in r.json()["detail"]
    big = data + b"\0" * 200_000
    r = client.post("/api/recordings/upload?name=big.mcap", content=big, headers={**AUTH, **raw})
    assert r.status_code == 413  # declared length over the bound
    r = client.post("/api/recordings/upload?name=big.mcap", content=iter([big[:150_000], big[150_000:]]),
                    headers={**AUTH, **raw})
    assert r.status_code == 413  # chunked, counted while written
    assert not [p for p in (tmp_path / "uploads").iterdir() if p.suffix in (".mcap", ".part")]
    r = client.post("/api/recordings/upload?name=my run.mcap", content=data, headers={**AUTH, **raw})
    assert r.status_code == 200, r.text
    entry = r.json()
    assert entry["id"].startswith("upload:") and entry["id"].endswith("-my_run.mcap")
    d = client.get("/api/recording", params={"id": entry["id"]}).json()
    assert d["vessels"] == [V] and d["source"] == "upload"
    assert client.get("/api/recordings").json()["recordings"][0]["id"] == entry["id"]


def test_uploads_named_recovered_are_bounded_and_listed_like_any_other(runs: Path,
                                                                      tmp_path: Path) -> None:
    """The store counted only what a runs folder lists, which leaves out ``*.recovered.mcap`` (its
    repaired copies): uploads named so were never pruned nor listed, so ``max_uploads`` did not
    bound the disk. Now every .mcap in the upload folder is an upload."""
    data = (write_run(tmp_path / "src", n=5) / "recording.mcap").read_bytes()
    raw = {**AUTH, "Content-Type": "application/octet-stream"}
    uploads = tmp_path / "uploads"
    settings = Settings(token=TOKEN, runs_dir=runs, upload_dir=uploads, max_uploads=2,
                        rate_limit_per_s=1e6, rate_limit_burst=1_000_000)
    with TestClient(create_app(MemoryHub().bus("gs"), settings)) as c:
        ids = []
        for i in range(5):
            r = c.post(f"/api/recordings/upload?name=x{i}.recovered.mcap", content=data, headers=raw)
            assert r.status_code == 200, r.text
            ids.append(r.json()["id"])
            os.utime(uploads / ids[-1].removeprefix("upload:"), (1e9 + i, 1e9 + i))  # in order
        assert len(list(uploads.glob("*.mcap"))) == 2
        listed = [e["id"] for e in c.get("/api/recordings").json()["recordings"] if e["source"] == "upload"]
        assert sorted(listed) == sorted(ids[-2:])
        assert c.get("/api/recording", params={"id": ids[0]}).status_code == 404  # pruned


def test_a_recording_that_does_not_read_is_refused_without_this_machines_paths(
        runs: Path, tmp_path: Path) -> None:
    """The 422 gave the reader's text, naming the file's absolute path (for an upload, the private
    upload folder). Now the recording is named by its id; the log keeps the full text."""
    garbage = b"\x89MCAP0\r\n" + b"garbage" * 10
    (runs / "broken").mkdir(parents=True)
    (runs / "broken" / "recording.mcap").write_bytes(garbage)
    settings = Settings(token=TOKEN, runs_dir=runs)  # uploads: a private temporary folder
    with TestClient(create_app(MemoryHub().bus("gs"), settings)) as c:
        r = c.get("/api/recording", params={"id": "broken"})
        assert r.status_code == 422 and "broken/recording.mcap" in r.json()["detail"], r.text
        up = c.post("/api/recordings/upload?name=b.mcap", content=garbage,
                    headers={**AUTH, "Content-Type": "application/octet-stream"})
        assert up.status_code == 422 and "upload:" in up.json()["detail"], up.text
        for detail in (r.json()["detail"], up.json()["detail"]):
            assert str(tmp_path) not in detail and tempfile.gettempdir() not in detail, detail
            assert "seaway-gs-uploads" not in detail, detail


def test_the_page_is_served_with_every_module_it_imports(client: TestClient) -> None:
    import re

    page = client.get("/")
    assert page.status_code == 200 and 'src="/static/js/main.js"' in page.text
    seen, todo = set(), ["/static/js/main.js"]
    while todo:
        path = todo.pop()
        r = client.get(path)
        assert r.status_code == 200, path
        seen.add(path)
        for rel in re.findall(r'from "\./([a-z]+\.js)"', r.text):
            if f"/static/js/{rel}" not in seen:
                todo.append(f"/static/js/{rel}")
    assert {"/static/js/map.js", "/static/js/store.js", "/static/js/replay.js"} <= seen
    assert client.get("/static/style.css").status_code == 200
    assert client.get("/static/../app.py").status_code == 404
    cfg = client.get("/api/config").json()
    assert cfg["tiles_url"] is None and "cc-empc" in cfg["controllers"]


def test_map_tiles_from_a_local_folder_or_a_url_template(tmp_path: Path) -> None:
    tiles = tmp_path / "tiles"
    (tiles / "3" / "6").mkdir(parents=True)
    (tiles / "3" / "6" / "3.png").write_bytes(b"\x89PNG\r\n\x1a\n tile")
    hub = MemoryHub()
    with TestClient(create_app(hub.bus("gs"), Settings(token=TOKEN, tiles=str(tiles)))) as c:
        assert c.get("/api/config").json()["tiles_url"] == "/tiles/{z}/{x}/{y}.png"
        r = c.get("/tiles/3/6/3.png")
        assert r.status_code == 200 and r.headers["content-type"] == "image/png"
        assert c.get("/tiles/3/8/3.png").status_code == 404  # x beyond 2^z
        assert c.get("/tiles/3/5/3.png").status_code == 404  # not in the folder
        assert c.get("/tiles/3/6/..%2F..%2Fsecret.png").status_code in (404, 422)
    url = "https://tiles.example.org/{z}/{x}/{y}.png"
    assert Settings(token=TOKEN, tiles=url).tiles_url == url
    with pytest.raises(ValueError, match="needs"):
        Settings(token=TOKEN, tiles="https://tiles.example.org/{z}/{x}.png")
    with pytest.raises(ValueError, match="neither"):
        Settings(token=TOKEN, tiles=str(tmp_path / "no-such-folder"))
