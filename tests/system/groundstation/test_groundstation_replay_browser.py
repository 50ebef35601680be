"""Replay in a real browser (Debian's chromium under Playwright) against the real ground station
process: a recording the recorder's own writer wrote, opened on the page while the frames after
the first answer are held back (Playwright holds those requests), then scrubbed past what has
arrived. The page must not show the frames it has, aged to the time asked for, as the vessel's
current state (they used to show, marked stale); it waits at the loaded edge and goes to the time
asked for once the frames are there. Opening a run still being recorded must leave its folder as
it was (file names and modification times): the repaired copy goes to the recorder's cache."""

from __future__ import annotations

import re
import signal
import threading
from pathlib import Path
from typing import Any

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionStatus, StateEstimate
from seaway_recorder.core import RecordingWriter

from tests.conftest import BIN, wait_for

pytestmark = [pytest.mark.system, pytest.mark.slow]
V = "replay-boat"
T0 = 1_700_000_000_000_000_000
PERIOD_NS = 100_000_000
PERIODS = 3000  # 300 s of recorded time
TARGET_S = 250.0


def _state(i: int) -> StateEstimate:
    return StateEstimate(stamp_ns=T0 + i * PERIOD_NS, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.1 * i,
                         y_m=0.5, psi_rad=0.0)


def _write(w: RecordingWriter, spec: keys.KeySpec, msg: Any, at_ns: int) -> None:
    assert w.write(spec.key(V), msg.encode(), f"application/json;{msg.SCHEMA}", at_ns)


def _record(folder: Path, periods: int, finish: bool) -> RecordingWriter:
    folder.mkdir(parents=True)
    w = RecordingWriter(folder / "recording.mcap", foxglove=False, chunk_size=64 * 1024)
    w.open(T0)
    for i in range(periods):
        t = T0 + i * PERIOD_NS
        _write(w, keys.NAV_STATE, _state(i), t)
        _write(w, keys.MISSION_STATUS, MissionStatus(stamp_ns=t, state="active", mission_id="m1",
                                                     active_leg=1, waypoint_count=2,
                                                     cross_track_m=0.2, energy_used_j=float(i)), t)
        if i % 10 == 9:
            w.flush()  # a chunk a second, as the recorder's flush interval ends them
    if finish:
        w.close(T0 + periods * PERIOD_NS)
    else:
        w.flush()
    return w


def _snapshot(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_mtime_ns for p in sorted(folder.rglob("*"))}


def test_scrubbing_past_the_loaded_part_never_shows_old_frames_as_current(
        procs, zenoh_env, tmp_path: Path, browser) -> None:
    runs = tmp_path / "runs"
    _record(runs / "done", PERIODS, finish=True)
    live_writer = _record(runs / "live", 200, finish=False)  # its recorder still writing
    (runs / "live" / "logs").mkdir()
    (runs / "live" / "logs" / "recorder.log").write_text("recording\n")
    before = _snapshot(runs / "live")
    env = {**zenoh_env, "SEAWAY_REPAIR_DIR": str(tmp_path / "repairs")}
    gs = procs.start([str(BIN / "seaway-groundstation"), "--port", "0", "--runs-dir", str(runs)],
                     env, "groundstation")
    base = wait_for(lambda: re.search(r"groundstation: (http://127\.0\.0\.1:\d+/)", procs.log(gs)),
                    60, what="the ground station's address line").group(1)
    held: list[Any] = []

    def hold_after_the_first(route: Any) -> None:
        start = float(re.search(r"start_s=([0-9.e+-]+)", route.request.url).group(1))
        if start > 0 and "id=done" in route.request.url:
            held.append(route)
        else:
            route.continue_()

    page = browser.new_page(viewport={"width": 1400, "height": 950})
    try:
        page.route("**/api/recording/frames*", hold_after_the_first)
        page.goto(base + "?view=replay")
        page.wait_for_function("document.querySelector('#recording-select option[value=done]')")
        page.select_option("#recording-select", "done")
        page.click("#recording-open")
        page.wait_for_function("window.seaway.player.frames.length > 0")
        for _ in range(300):  # Playwright hands requests to the handler only while it is called
            if held:
                break
            page.wait_for_timeout(100)
        assert held, "the page never asked for the frames after the first answer"
        loaded = page.evaluate("window.seaway.player.loadedTo")
        assert 0 < loaded < TARGET_S
        page.evaluate(f"""() => {{ const s = document.getElementById('scrub');
            s.value = {TARGET_S}; s.dispatchEvent(new Event('input')); }}""")
        page.wait_for_timeout(1500)  # renders happen at most ten a second; give it several
        shown = page.evaluate("""(name) => { const p = window.seaway.player;
            const v = p.store.vessel(name);
            return {t: p.t, loadedTo: p.loadedTo, wanted: p.wanted, x: v.message('state')?.x_m,
                    stale: v.stale('state', p.t), badge: !document.getElementById('map-stale').hidden,
                    time: document.getElementById('replay-time').textContent}; }""", V)
        # Not at 250 s with the state of ~2 s aged 248 s: at the loaded edge, the state current.
        assert shown["t"] <= shown["loadedTo"] + 1e-9, shown
        assert not shown["stale"] and not shown["badge"], shown
        assert shown["wanted"] == pytest.approx(TARGET_S) and "loading" in shown["time"], shown
        # The first frames are shown while the rest is held back.
        assert shown["x"] is not None and shown["x"] < loaded + 1, shown
        page.screenshot(path=str(tmp_path / "replay-waiting.png"))
        for route in held:
            route.continue_()
        page.unroute("**/api/recording/frames*")
        # Once the frames are there, the time asked for, with the state recorded then.
        page.wait_for_function(f"Math.abs(window.seaway.player.t - {TARGET_S}) < 0.01", timeout=60_000)
        at = page.evaluate("""(name) => { const p = window.seaway.player, v = p.store.vessel(name);
            return {x: v.message('state').x_m, stale: v.stale('state', p.t),
                    badge: !document.getElementById('map-stale').hidden}; }""", V)
        assert at["x"] == pytest.approx(TARGET_S, abs=0.2) and not at["stale"], at
        page.wait_for_timeout(300)
        assert not page.evaluate("!document.getElementById('map-stale').hidden")
        page.screenshot(path=str(tmp_path / "replay-at-target.png"))

        # The run still being recorded: opened, its frames read, its folder untouched.
        page.select_option("#recording-select", "live")
        page.click("#recording-open")
        page.wait_for_function("window.seaway.player.detail?.id === 'live' "
                               "&& window.seaway.player.loadedTo === Infinity", timeout=60_000)
        assert page.evaluate("window.seaway.player.frames.length") > 100
        assert _snapshot(runs / "live") == before  # no file added, none written
    finally:
        page.close()
        live_writer.close(T0 + 200 * PERIOD_NS)
    assert list((tmp_path / "repairs").glob("*/recording.*.recovered.mcap"))  # read through a copy
    procs.stop(gs, signal.SIGTERM, timeout_s=10)


def test_a_reloaded_live_page_keeps_the_plots_history_from_the_recording(
        procs, zenoh_env, tmp_path: Path, browser) -> None:
    """The live page loaded after 30 s of a run: its speed plot and trail start at the run's start
    (from the run's recording, still being written), then go on with the live frames."""
    from seaway.runtime.bus import Bus

    runs = tmp_path / "runs"
    recorded = 300
    writer = _record(runs / "live", recorded, finish=False)
    env = {**zenoh_env, "SEAWAY_REPAIR_DIR": str(tmp_path / "repairs")}
    gs = procs.start([str(BIN / "seaway-groundstation"), "--port", "0", "--run-dir",
                      str(runs / "live")], env, "groundstation")
    base = wait_for(lambda: re.search(r"groundstation: (http://127\.0\.0\.1:\d+/)", procs.log(gs)),
                    60, what="the ground station's address line").group(1)
    before = _snapshot(runs / "live")  # with the ground station's own address file in it
    stop = threading.Event()
    try:
        with Bus.open(V) as bus:  # the vessel goes on where the recording is
            bus.declare_alive("estimator")
            pubs = {s: bus.publisher(s) for s in (keys.NAV_STATE, keys.MISSION_STATUS)}

            def publish() -> None:
                i = recorded
                while not stop.wait(0.1):
                    t = T0 + i * PERIOD_NS
                    pubs[keys.NAV_STATE].put(_state(i))
                    pubs[keys.MISSION_STATUS].put(MissionStatus(
                        stamp_ns=t, state="active", mission_id="m1", active_leg=1, waypoint_count=2,
                        cross_track_m=0.2, energy_used_j=float(i)))
                    i += 1

            publisher = threading.Thread(target=publish, daemon=True)
            publisher.start()
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 950})
                errors: list[str] = []
                page.on("pageerror", lambda e: errors.append(str(e)))
                page.goto(base)
                page.wait_for_function("(name) => window.seaway.app.live.vessels.get(name)"
                                       "?.series.speed.t.length > 300", arg=V, timeout=60_000)
                got = page.evaluate("""(name) => { const v = window.seaway.app.live.vessels.get(name);
                    const s = v.series.speed;
                    return {n: s.t.length, first: s.t[0], last: s.t[s.t.length - 1],
                            ordered: s.t.every((t, i) => i === 0 || t >= s.t[i - 1]),
                            trail0: v.trail[0], x: v.message('state').x_m}; }""", V)
                page.close()
                assert _snapshot(runs / "live") == before  # read, never written
            finally:  # the publisher stops before the bus it puts on is closed
                stop.set()
                publisher.join(5.0)
    finally:
        stop.set()
        writer.close(T0 + recorded * PERIOD_NS)
    # From the run's start (the recording) to the live state, in time order, no doubles.
    assert got["first"] == 0 and got["trail0"][0] == pytest.approx(0.0), got
    assert got["ordered"] and got["last"] > (recorded - 1) * PERIOD_NS / 1e9, got
    assert got["x"] >= recorded * 0.1 - 1e-6, got
    assert not errors, errors
    procs.stop(gs, signal.SIGTERM, timeout_s=10)


def test_a_damaged_recording_says_on_the_page_where_its_replay_stops_and_why(
        procs, zenoh_env, tmp_path: Path, browser) -> None:
    """A chunk with flipped bytes is met only as the frames are cut, after the page showed the
    recording's detail: the replay stopped early with no word. The page now says which recording,
    what is wrong and how to repair it."""
    runs = tmp_path / "runs"
    _record(runs / "damaged", PERIODS, finish=True)
    path = runs / "damaged" / "recording.mcap"
    data = bytearray(path.read_bytes())
    for i in range(len(data) // 2, len(data) // 2 + 16):
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))
    gs = procs.start([str(BIN / "seaway-groundstation"), "--port", "0", "--runs-dir", str(runs)],
                     zenoh_env, "groundstation")
    base = wait_for(lambda: re.search(r"groundstation: (http://127\.0\.0\.1:\d+/)", procs.log(gs)),
                    60, what="the ground station's address line").group(1)
    page = browser.new_page(viewport={"width": 1400, "height": 950})
    try:
        page.goto(base + "?view=replay")
        page.wait_for_function("document.querySelector('#recording-select option[value=damaged]')")
        page.select_option("#recording-select", "damaged")
        page.click("#recording-open")
        page.wait_for_function("window.seaway.player.loadedTo === Infinity", timeout=60_000)
        page.wait_for_function("document.getElementById('recording-info').textContent"
                               ".includes('could not be read')", timeout=10_000)
        info = page.evaluate("document.getElementById('recording-info').textContent")
        assert "'damaged'" in info and "seaway record recover" in info, info
        assert 0 < page.evaluate("window.seaway.player.frames.length") < PERIODS
    finally:
        page.close()
    procs.stop(gs, signal.SIGTERM, timeout_s=10)
