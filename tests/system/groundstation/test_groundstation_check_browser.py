"""The mission check on the page before sending, in a real browser (Debian's chromium driven by
Playwright), issue #57 item 3: the real ``seaway-groundstation`` on a real Zenoh session, the test
playing the vessel's estimator and controller (its state, an energy budget with little battery
left, and ``mission/set``, whose requests it keeps).

The page checks the drafted mission with the controller's own check before it sends anything:
"Check" shows the figures and the refusal; "Send" on a refused mission asks whether to force it,
sends nothing when declined, and sends it with ``force`` when accepted.
"""

from __future__ import annotations

import math
import signal
import threading
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    EnergyBudget,
    MissionRequest,
    MissionStatus,
    NavOrigin,
    Reply,
    StateEstimate,
    VehicleStatus,
)
from seaway.runtime.bus import Bus
from seaway.vessel.frames import GeoOrigin

from tests.conftest import wait_for
from tests.system.groundstation.helpers import http, joules, pumped, start_groundstation

pytestmark = pytest.mark.system
VESSEL = "check-boat"
ORIGIN = GeoOrigin(math.radians(47.3), math.radians(8.5), 400.0)
LONG_M = [(0.0, 0.0), (60.0, 0.0), (60.0, 50.0)]
"""A mission far longer than the battery left allows."""
BATTERY_J, RESERVE_J = 40.0, 10.0



def test_the_page_checks_a_mission_before_sending_and_sends_a_refused_one_only_forced(
        procs, zenoh_env, browser) -> None:
    gs, base, token = start_groundstation(procs, zenoh_env)
    stop = threading.Event()
    sent: list[MissionRequest] = []

    def on_mission(req: MissionRequest) -> Reply:
        sent.append(req)
        return Reply.accept(1, "mission started")

    with Bus.open(VESSEL) as bus:
        bus.queryable(keys.MISSION_SET, on_mission)
        bus.declare_alive("controller")
        pubs = {spec: bus.publisher(spec) for spec in (
            keys.NAV_ORIGIN, keys.NAV_STATE, keys.MISSION_STATUS, keys.MISSION_ENERGY,
            keys.VEHICLE_STATUS)}

        def publish() -> None:  # 5 Hz: nothing goes stale
            k = 0
            while not stop.wait(0.2):
                k += 1
                t = time.time_ns()
                pubs[keys.NAV_ORIGIN].put(NavOrigin.make(stamp_ns=t, lat_rad=ORIGIN.lat_rad,
                                                         lon_rad=ORIGIN.lon_rad, alt_m=ORIGIN.alt_m))
                pubs[keys.NAV_STATE].put(StateEstimate.make(stamp_ns=t, u_mps=0.0, v_mps=0.0,
                                                            r_radps=0.0, x_m=0.0, y_m=0.0, psi_rad=0.0))
                pubs[keys.MISSION_STATUS].put(MissionStatus.make(stamp_ns=t, state="idle"))
                pubs[keys.VEHICLE_STATUS].put(VehicleStatus.make(
                    stamp_ns=t, autopilot="ardupilot", link_ok=True, armed=True, mode="MANUAL"))
                pubs[keys.MISSION_ENERGY].put(EnergyBudget.make(
                    stamp_ns=t, mission_id="before", energy_used_j=0.0, home_x_m=0.0, home_y_m=0.0,
                    battery_remaining_j=BATTERY_J, reserve_j=RESERVE_J, policy="return",
                    decision="none"))

        publisher = threading.Thread(target=publish, daemon=True)
        publisher.start()
        try:
            wait_for(lambda: http("GET", base + f"api/vessels/{VESSEL}")[0] == 200, 30,
                     what=f"{VESSEL} seen by the ground station")
            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(base + f"#token={token}")
            page.wait_for_function("document.getElementById('v-mode').textContent === 'MANUAL'",
                                   timeout=60_000)
            page.evaluate("() => { const m = window.seaway.map; m.center = [30, 25]; m.scale = 5; "
                          "m.invalidate(); }")
            page.click("#add-mode")
            box = page.locator("#map").bounding_box()
            for north, east in LONG_M:
                sx, sy = page.evaluate(f"window.seaway.map.toScreen({north}, {east})")
                page.mouse.click(box["x"] + sx, box["y"] + sy)
            page.wait_for_timeout(300)
            assert len(page.evaluate("window.seaway.app.draft")) == len(LONG_M)
            page.fill("#mission-id", "too-far")

            # "Check": the controller's figures and its refusal, nothing sent.
            page.click("#check-mission")
            page.wait_for_function("document.getElementById('check-verdict').textContent !== ''",
                                   timeout=30_000)
            shown = {i: page.locator(f"#{i}").text_content() for i in (
                "check-verdict", "check-length", "check-energy", "check-battery", "check-reasons")}
            assert "REFUSED" in shown["check-verdict"], shown
            length = page.locator("#check-length").text_content()
            assert float(length.split()[0]) == pytest.approx(110.0, abs=1.0)  # 60 m + 50 m
            assert joules(page.locator("#check-energy").text_content()) > BATTERY_J - RESERVE_J
            assert page.locator("#check-reasons li").count() >= 1
            assert not sent

            # "Send" on a refused mission: declining the force sends nothing ...
            asked: list[str] = []

            def answer(accept: bool):
                def on_dialog(d) -> None:
                    asked.append(d.message)
                    d.accept() if accept else d.dismiss()
                return on_dialog

            page.once("dialog", answer(False))
            page.click("#send-mission")
            # Playwright dispatches the dialog to its handler only inside its own calls: poll with one.
            pumped(page, lambda: asked, "the page asking whether to force the mission")
            page.wait_for_function("!document.getElementById('send-mission').disabled", timeout=10_000)
            assert "refuses" in asked[0] and not sent
            # ... accepting it sends the mission forced.
            page.once("dialog", answer(True))
            page.click("#send-mission")
            pumped(page, lambda: sent, "the forced mission")
            assert sent[0].mission_id == "too-far" and sent[0].force
            assert not errors, errors
        finally:
            stop.set()
            publisher.join(5)
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
