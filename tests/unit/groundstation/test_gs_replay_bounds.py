"""Replay at its edges: answers and memory bounded however long the recording, several clients
replaying different recordings at once, damaged and cut recordings reported by name, and query
parameters and uploads that make no sense refused clearly."""

from __future__ import annotations

import json
import threading
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from seaway.runtime.memory_bus import MemoryHub
from seaway_groundstation.app import create_app
from seaway_groundstation.framestore import FrameStore
from seaway_groundstation.recordings import Library, RunsFolder, UploadStore
from seaway_groundstation.replay import ReplayFrame
from seaway_groundstation.routes import replay as replay_routes
from seaway_groundstation.settings import Settings

from tests.unit.groundstation.live_server import serve
from tests.unit.groundstation.test_gs_replay import AUTH, TOKEN, V, write_run

RAW = {**AUTH, "Content-Type": "application/octet-stream"}


@pytest.fixture
def runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("SEAWAY_REPAIR_DIR", str(tmp_path / "repairs"))  # a cut file's repaired copy
    return tmp_path / "runs"


@pytest.fixture
def client(runs: Path, tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(token=TOKEN, runs_dir=runs, upload_dir=tmp_path / "uploads")
    with TestClient(create_app(MemoryHub().bus("gs"), settings)) as c:
        yield c


def read_all(get: Any, ref: str, span_s: float = 120.0) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Every frame of ``ref`` as the page reads them (``replay.js``: from each answer's
    ``loaded_to_s`` on); (frames, answers without their frames)."""
    d = get("/api/recording", id=ref)
    frames: list[dict[str, Any]] = []
    answers: list[dict[str, Any]] = []
    loaded = 0.0
    while loaded < d["duration_s"] + 1:
        assert len(answers) < 2000, "no progress"
        w = get("/api/recording/frames", id=ref, start_s=loaded, end_s=loaded + span_s)
        frames += w.pop("frames")
        answers.append(w)
        loaded = max(loaded, w["loaded_to_s"])
    return frames, answers


def test_an_answer_is_bounded_and_the_page_takes_up_where_it_ends(
        client: TestClient, runs: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``start_s=0&end_s=1e7`` gave every frame in one body: an hour of one vessel at 10 Hz was a
    65 MB answer, built two or three times over in the server's memory. Now an answer holds at
    most ``MAX_FRAMES_BYTES`` of frames and says up to when it is whole (``loaded_to_s``); read on
    from there, every frame comes exactly once."""
    monkeypatch.setattr(replay_routes, "MAX_FRAMES_BYTES", 50_000)
    write_run(runs / "long", n=600)

    def get(path: str, **q: Any) -> dict[str, Any]:
        return client.get(path, params=q).json()

    whole = client.get("/api/recording/frames", params={"id": "long", "start_s": 0, "end_s": 1e7})
    w = whole.json()
    assert whole.status_code == 200 and 0 < w["count"] == len(w["frames"])
    assert len(whole.content) < 50_000 + 1_000  # the bound and the head
    assert w["loaded_to_s"] < 1e7 and w["frames"][-1]["t_s"] < w["loaded_to_s"]
    frames, answers = read_all(get, "long")
    d = get("/api/recording", id="long")
    times = [f["t_s"] for f in frames]
    assert len(answers) > 5 and d["complete"] and len(frames) == d["frame_count"] > 500
    assert times == sorted(times) and len(set(times)) == len(times)  # each once, in order
    assert all(a["start_s"] < a["loaded_to_s"] for a in answers)  # always further


def test_frames_of_one_time_are_never_split_and_one_larger_than_the_bound_still_goes() -> None:
    store = FrameStore(block_bytes=300)
    frames = [ReplayFrame(t, json.dumps({"vessel": v, "pad": "x" * 40}))
              for t in (0.05, 0.1, 0.15) for v in ("a", "b", "c")]
    store.append(frames)
    one_time = len(store.window(0.0, 0.1, 1 << 20)[0])  # the 3 frames of a time [bytes]
    text, count, upto = store.window(0.0, 1.0, max_bytes=one_time * 3 // 2)
    assert count == 3 and upto == 0.1 and [f["t_s"] for f in json.loads(text)] == [0.05] * 3
    text, count, upto = store.window(0.0, 1.0, max_bytes=one_time // 2)  # one time alone is more
    assert count == 3 and upto == 0.1
    text, count, upto = store.window(0.1, 1.0, max_bytes=one_time * 3)
    assert count == 6 and upto == 1.0
    assert [f["frame"]["vessel"] for f in json.loads(text)] == ["a", "b", "c"] * 2
    assert store.window(0.2, 1.0, 10) == (b"[]", 0, 1.0)


def test_a_timeline_keeps_its_frames_on_disk_not_in_memory(runs: Path) -> None:
    """Every frame's text stayed in memory: some 50 times the recording's size (65 MB for an hour
    of one vessel), for each of the recordings kept open. Now memory holds the block being filled
    and 16 bytes per frame; the rest is compressed in a temporary file, and reads back whole."""
    from seaway.recording import reader
    from seaway_groundstation.timeline import Timeline

    write_run(runs / "r", n=3000)
    files = reader.open_paths([runs / "r"])
    info = reader.read_info(files)
    tl = Timeline(files, info.summaries, info.start_ns, 20.0, 2.0)
    tl.frames.block_bytes = 64 << 10
    tl.start().wait(1e9, 120.0)
    assert tl.complete and len(tl.frames) == 3000
    text, count, _ = tl.window(0.0, 1e9, 1 << 30)
    assert count == 3000 and len(json.loads(text)) == 3000
    assert len(text) > 40 * (64 << 10)  # the frames' text ...
    assert len(tl.frames._tail) < 64 << 10 < tl.frames.disk_bytes < len(text) / 4  # ... is on disk


def test_the_recording_being_read_is_not_the_one_evicted(runs: Path, tmp_path: Path) -> None:
    """The cache was least recently *opened*: a page opens once and then reads frames for minutes,
    so a third client's open evicted the recording still being read, which was then cut again from
    its start at the reader's next request."""
    for name in ("a", "b", "c"):
        write_run(runs / name, n=20)
    lib = Library(RunsFolder(runs), UploadStore(tmp_path / "up", 2, 1 << 20), 20.0, 2.0, cache_size=2)
    a = lib.open("a")
    lib.open("b")
    assert lib.get("a") is a  # a client reads a's frames
    lib.open("c")  # evicts b, the least recently read
    assert lib.get("a") is a


def test_several_clients_replay_different_recordings_at_once(runs: Path) -> None:
    """Four pages replaying four recordings over a real server: each recording was opened (and cut
    from its start) again and again, as each open evicted another page's (two kept). Now each page
    reads every frame of its own recording, each recording opened once."""
    ids = [f"r{i}" for i in range(4)]
    for i, ref in enumerate(ids):
        write_run(runs / ref, n=200 + 50 * i)
    with serve(MemoryHub(), runs_dir=runs) as served:
        opened: list[str] = []
        load = served.gs.library._load

        def counted(ref: str, *args: Any) -> Any:
            opened.append(ref)
            return load(ref, *args)

        served.gs.library._load = counted  # type: ignore[method-assign]

        def get(path: str, **q: Any) -> dict[str, Any]:
            url = f"http://127.0.0.1:{served.port}{path}?{urllib.parse.urlencode(q)}"
            with urllib.request.urlopen(url, timeout=60) as r:
                return json.loads(r.read())

        got: dict[str, Any] = {}

        def page(ref: str) -> None:
            try:  # short spans: many requests, interleaved with the other pages'
                got[ref] = read_all(get, ref, span_s=2.0)[0]
            except Exception as err:
                got[ref] = err

        threads = [threading.Thread(target=page, args=(ref,)) for ref in ids]
        for t in threads:
            t.start()
        for t in threads:
            t.join(120)
        for i, ref in enumerate(ids):
            assert isinstance(got[ref], list), got[ref]
            assert len(got[ref]) == 200 + 50 * i, ref
        assert sorted(opened) == ids


def _flip_middle(path: Path) -> None:
    data = bytearray(path.read_bytes())
    for i in range(len(data) // 2, len(data) // 2 + 16):
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))


def test_a_damaged_chunk_is_reported_to_the_page_by_name_and_others_read_on(
        client: TestClient, runs: Path, tmp_path: Path) -> None:
    """A chunk with flipped bytes ended the frames there, the answers saying ``complete`` and
    nothing else: the page (which had the detail before the damage was met) showed a replay that
    stopped early, no reason given, and the note said neither which recording nor how to repair it.
    Now each answer from there carries ``error``: the recording, the damaged chunk and the repair."""
    write_run(runs / "damaged", n=600, chunk_size=4096)
    _flip_middle(runs / "damaged" / "recording.mcap")
    write_run(runs / "fine", n=100)

    def get(path: str, **q: Any) -> dict[str, Any]:
        r = client.get(path, params=q)
        assert r.status_code == 200, r.text
        return r.json()

    frames, answers = read_all(get, "damaged")
    assert 0 < len(frames) < 600  # what came before the damage
    error = answers[-1]["error"]
    assert error and "'damaged'" in error and "chunk" in error and "seaway record recover" in error
    assert str(tmp_path) not in error
    assert error in get("/api/recording", id="damaged")["notes"]
    fine, fine_answers = read_all(get, "fine")  # the server reads on, other recordings whole
    assert len(fine) == 100 and not any(a["error"] for a in fine_answers)


def test_a_cut_recording_says_it_was_read_through_a_repaired_copy(client: TestClient, runs: Path,
                                                                    tmp_path: Path) -> None:
    """A file cut short (a crash) opened without a word: the replay ended early as if the run had.
    Now the detail's notes say it was not finished and what was kept, by its name in the API."""
    path = write_run(runs / "cut", n=600, chunk_size=4096) / "recording.mcap"
    path.write_bytes(path.read_bytes()[: path.stat().st_size * 2 // 3])
    d = client.get("/api/recording", params={"id": "cut"}).json()
    assert 0 < d["duration_s"] < 60 and d["vessels"] == [V]
    (note,) = d["notes"]
    assert "'cut'" in note and "not finished" in note and "messages kept" in note
    assert str(tmp_path) not in note


@pytest.mark.parametrize(("start", "end", "field"), [
    ("nan", "10", "start_s"), ("0", "nan", "end_s"), ("inf", "10", "start_s"), ("0", "inf", "end_s"),
    ("-1", "10", "start_s"), ("0", "-5", "end_s"), ("0", "1e308", "end_s"), ("1e308", "1e308", "start_s"),
    ("10", "5", "end_s"), ("5", "5", "end_s"), ("abc", "1", "start_s"), ("0x10", "20", "start_s"),
])
def test_absurd_spans_are_refused_naming_the_parameter(client: TestClient, runs: Path,
                                                       start: str, end: str, field: str) -> None:
    write_run(runs / "r", n=10)
    r = client.get(f"/api/recording/frames?id=r&start_s={start}&end_s={end}")
    assert r.status_code == 422 and field in json.dumps(r.json()["detail"])
    assert client.get("/api/recording/frames?id=r&start_s=0&end_s=1e7").status_code == 200


def test_an_upload_of_joined_recordings_is_refused_and_not_kept(client: TestClient, tmp_path: Path) -> None:
    one = (write_run(tmp_path / "src", n=20) / "recording.mcap").read_bytes()
    r = client.post("/api/recordings/upload?name=joined.mcap", content=one + one, headers=RAW)
    assert r.status_code == 422 and "more than one recording" in r.json()["detail"]
    assert "seaway record recover" in r.json()["detail"]
    assert not list((tmp_path / "uploads").glob("*.mcap"))
