"""The operator's page in a real browser (Debian's chromium driven by Playwright) against the real
``sim`` profile: the real-time stack with the simulated PX4 behind MAVLink, vehicle_io, the
estimator, the controller, the recorder and the ground station, as ``./run`` starts them.

Waypoints are added by clicking the map, the mission is sent from the page (which starts it), the
vessel is watched to the last waypoint, and the energy and cross-track figures the page shows are
checked against ``seaway report`` on the run's recording. Then the run's recording is opened in the
page's replay view and scrubbed to the end. Screenshots go to a folder under the test's tmp dir
(printed); docs/groundstation/ holds copies of good ones.

The real-time profile, not the lockstep one: it is what an operator sees (wall-clock staleness,
MAVLink, the launcher's arming), and the mission is short enough (about a minute) to fly in real
time.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import BIN, wait_for
from tests.system.groundstation.helpers import joules

pytestmark = [pytest.mark.system, pytest.mark.slow]

BOX_M = [(0.0, 0.0), (16.0, 0.0), (16.0, 12.0), (2.0, 12.0)]
"""The mission clicked on the map: local NED (north, east) [m], from where the vessel starts."""
CLICK_TOLERANCE_M = 0.25
"""A click lands within a pixel of where it was aimed; at the test's zoom that is under 0.25 m."""


def number(text: str) -> float:
    m = re.search(r"-?\d+(?:\.\d+)?", text)
    assert m, f"no number in {text!r}"
    return float(m.group())


def test_plan_fly_check_and_replay_a_mission_from_the_page(procs, zenoh_env, tmp_path, browser) -> None:
    shots = tmp_path / "screenshots"
    shots.mkdir()
    print(f"\nscreenshots: {shots}")
    runs = tmp_path / "runs"
    run = runs / "browser-run"
    launcher = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--run-dir", str(run),
                            "--no-mission", "--stay"], zenoh_env, "launcher")
    address = run / "groundstation" / "address.json"

    def launched(done: str):
        def check() -> bool:
            if launcher.poll() is not None:
                pytest.fail(f"the launcher exited ({launcher.returncode}):\n{procs.log(launcher)[-3000:]}")
            return done in procs.log(launcher)
        return check

    wait_for(launched("arm: accepted"), 240, interval_s=0.2, what="the stack ready and armed")
    assert oct(address.stat().st_mode & 0o777) == "0o600"
    page_url = json.loads(address.read_text())["page"]

    page = browser.new_page(viewport={"width": 1500, "height": 1000})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("dialog", lambda d: d.accept())  # the page asks before moving the vessel
    page.goto(page_url)
    # The token came in the fragment: kept for the tab, gone from the address bar.
    page.wait_for_function("sessionStorage.getItem('seaway.groundstation.token') !== null")
    assert "#token" not in page.url
    page.wait_for_function("document.getElementById('v-link').textContent === 'up'", timeout=60_000)
    page.wait_for_function("document.getElementById('v-armed').textContent === 'armed'", timeout=60_000)
    page.screenshot(path=str(shots / "1-live-idle.png"))

    # Plan: zoom so the box fills the map, then click its corners.
    page.evaluate("() => { const m = window.seaway.map; m.center = [7, 6]; m.scale = 14; m.invalidate(); }")
    page.click("#add-mode")
    box = page.locator("#map").bounding_box()
    for north, east in BOX_M:
        sx, sy = page.evaluate(f"window.seaway.map.toScreen({north}, {east})")
        page.mouse.click(box["x"] + sx, box["y"] + sy)
    page.wait_for_timeout(300)
    draft = page.evaluate("window.seaway.app.draft")
    assert len(draft) == len(BOX_M)
    for (north, east), wp in zip(BOX_M, draft, strict=True):
        assert abs(wp["x_m"] - north) < CLICK_TOLERANCE_M and abs(wp["y_m"] - east) < CLICK_TOLERANCE_M, draft
    page.fill("#coa", "2")
    page.fill("#task-power", "250")
    page.fill("#mission-id", "browser-box")
    page.screenshot(path=str(shots / "2-planned.png"))

    # Upload: the mission goes to the vessel, which starts it; the page shows the vessel's answer.
    page.click("#send-mission")
    page.wait_for_selector(".msg.ok >> text=Mission browser-box: accepted", timeout=30_000)
    page.wait_for_function("document.getElementById('p-state').textContent === 'active'", timeout=30_000)
    page.wait_for_function("document.getElementById('p-id').textContent === 'browser-box'")
    page.wait_for_timeout(15_000)
    page.screenshot(path=str(shots / "3-live-flying.png"))
    # The controller's energy budget (mission/energy) while it flies: to finish and to get home.
    page.wait_for_function("document.getElementById('e-source').textContent === 'mission/energy'",
                           timeout=30_000)
    assert joules(page.locator("#e-finish").text_content() or "") > 0
    assert joules(page.locator("#e-home").text_content() or "") > 0

    # Watch it reach the last waypoint.
    page.wait_for_function("document.getElementById('p-state').textContent === 'complete'", timeout=240_000)
    page.wait_for_function("document.getElementById('m-travel-time').textContent !== '–'", timeout=30_000)
    page.wait_for_timeout(2500)  # the live metrics poll once more after completion
    shown = {name: page.locator(f"#{name}").text_content() or ""
             for name in ("m-energy-used", "m-energy", "m-xte-avg", "m-travel-time")}
    page.screenshot(path=str(shots / "4-live-complete.png"))
    assert not errors, errors

    # The stack stops: the page says the link is lost and shows every live figure stale.
    procs.stop(launcher, signal.SIGINT, timeout_s=120)
    page.wait_for_selector(".msg.error >> text=Link to the ground station lost", timeout=30_000)
    assert page.locator("#link").text_content() == "link lost"
    page.wait_for_function("[...document.querySelectorAll('#plots canvas')]"
                           ".every(c => c.dataset.stale === 'true')", timeout=10_000)
    assert page.locator("#map-stale").is_visible()
    assert page.locator("[data-stale='mission']").first.is_visible()
    page.screenshot(path=str(shots / "5-link-lost.png"))

    # The run's report, for the mission the page sent (from the ground station's journal).
    journal = (run / "groundstation" / "requests.jsonl").read_text().splitlines()
    entries = [json.loads(line) for line in journal]
    (sent,) = [e["message"] for e in entries if e["request"] == "mission/set" and e["outcome"] == "accepted"]
    assert sent["mission_id"] == "browser-box"
    mission_file = tmp_path / "mission.json"
    mission_file.write_text(json.dumps(sent))
    def report(*extra: str) -> dict:
        out = subprocess.run([str(BIN / "seaway"), "report", str(run), "--mission", str(mission_file),
                              "--json", "--no-plots", *extra],
                             capture_output=True, text=True, timeout=300, env=zenoh_env)
        assert out.returncode == 0, out.stderr
        return json.loads(out.stdout)["metrics"]

    truth = report("--out", str(run / "report"))  # the run's report: the simulator's truth
    estimate = report("--state", "nav/state", "--out", str(tmp_path / "report-estimate"))
    assert truth["completed"] and estimate["completed"]
    print(f"page: {shown}\nreport (sim/truth): energy {truth['energy_j']:.1f} J, avg cross-track "
          f"{truth['avg_cross_track_m']:.3f} m, travel {truth['travel_time_s']:.1f} s\n"
          f"report (nav/state): avg cross-track {estimate['avg_cross_track_m']:.3f} m, travel "
          f"{estimate['travel_time_s']:.1f} s")
    # Energy: the controller's own account (alpha T^2 + T^w of its commands) and the ground
    # station's (the same from the commands it heard) against the simulator's integral.
    assert joules(shown["m-energy-used"]) == pytest.approx(truth["energy_j"], rel=0.02)
    assert joules(shown["m-energy"]) == pytest.approx(truth["energy_j"], rel=0.03)
    assert number(shown["m-travel-time"]) == pytest.approx(truth["travel_time_s"], abs=1.0)
    # Cross-track: the page computes the report's metric on the estimate (nav/state as heard
    # live), so it matches the report on the recorded nav/state; the truth differs by the
    # estimator's error, which on the lake (GNSS noise, gusts) is about a tenth of a metre.
    assert number(shown["m-xte-avg"]) == pytest.approx(estimate["avg_cross_track_m"], abs=0.01, rel=0.05)
    assert number(shown["m-xte-avg"]) == pytest.approx(truth["avg_cross_track_m"], abs=0.25)

    # Replay: a ground station over the runs folder (the stack is gone), the run opened, scrubbed.
    gs = procs.start([str(BIN / "seaway-groundstation"), "--port", "0", "--runs-dir", str(runs)],
                     zenoh_env, "groundstation-replay")
    line = wait_for(lambda: re.search(r"groundstation: (http://\S+) token", procs.log(gs)), 60,
                    what="the replay ground station's address")
    page.goto(line.group(1) + "?view=replay")
    page.wait_for_selector(f"#recording-select option[value='{run.name}']", state="attached", timeout=30_000)
    page.select_option("#recording-select", run.name)
    page.click("#recording-open")
    page.wait_for_function("window.seaway.player.loadedTo === Infinity", timeout=120_000)
    duration = page.evaluate("window.seaway.player.detail.duration_s")
    page.fill("#scrub", str(duration / 2))
    page.wait_for_timeout(500)
    page.screenshot(path=str(shots / "6-replay-middle.png"))
    page.fill("#scrub", str(duration))
    page.wait_for_function("document.getElementById('p-state').textContent === 'complete'", timeout=10_000)
    page.wait_for_timeout(500)
    page.screenshot(path=str(shots / "7-replay-end.png"))
    # The end of the recording is the end of the mission: the same figures as live, and the
    # report's beside them.
    assert joules(page.locator("#m-energy-used").text_content() or "") == pytest.approx(
        joules(shown["m-energy-used"]), rel=0.01)
    replay_energy = joules(page.locator("#m-energy").text_content() or "")
    # The report's, as shown: three significant digits (kJ) round by at most 0.5 %.
    assert replay_energy == pytest.approx(truth["energy_j"], rel=0.005)
    assert page.locator("#p-id").text_content() == "browser-box"
    # The energy budget replays too: the last one recorded for the mission is the one shown.
    from seaway.contract import keys
    from seaway.recording import reader

    dec = reader.decode_vessel(reader.open_paths([run]), None, [keys.MISSION_ENERGY.suffix])
    last = [b for b in dec.get(keys.MISSION_ENERGY.suffix) if b.mission_id == "browser-box"][-1]
    assert page.locator("#e-source").text_content() == "mission/energy"
    assert joules(page.locator("#e-finish").text_content() or "") == pytest.approx(
        last.energy_to_go_j, rel=0.005, abs=0.01)
    assert joules(page.locator("#e-home").text_content() or "") == pytest.approx(
        last.energy_to_home_j, rel=0.005, abs=0.01)
    plan = page.evaluate("window.seaway.map.model.plan")
    assert plan["mission_id"] == "browser-box" and len(plan["waypoints_m"]) == len(BOX_M)
    assert not errors, errors
    procs.stop(gs, signal.SIGTERM, timeout_s=15)

    keep = os.environ.get("SEAWAY_KEEP_SCREENSHOTS")
    if keep:  # to refresh docs/groundstation/: SEAWAY_KEEP_SCREENSHOTS=docs/groundstation
        Path(keep).mkdir(parents=True, exist_ok=True)
        for p in shots.glob("*.png"):
            shutil.copy(p, Path(keep) / p.name)
