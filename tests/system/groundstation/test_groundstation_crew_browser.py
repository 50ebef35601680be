"""The vehicle panel as a crew reads it, in a real browser (Debian's chromium driven by Playwright),
issue #59: the real ``seaway-groundstation`` process on a real Zenoh session, the test playing the
vessel's vehicle_io, estimator and controller.

Shown and checked against what was published: battery percent and voltage with the autopilot's own
flag, energy left and reserve, GNSS fix, position (metres and degrees through the origin), heading,
speed over ground, the real mode in the mode box (it used to say HOLD whatever the mode), the
mission's ETA, energies in kJ; the page says it is read-only without the token, and one click sends
one request.
"""

from __future__ import annotations

import math
import re
import signal
import threading
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    BatteryState,
    GnssFix,
    MissionStatus,
    ModeRequest,
    NavOrigin,
    Reply,
    StateEstimate,
    VehicleStatus,
)
from seaway.runtime.bus import Bus
from seaway.vessel.frames import GeoOrigin

from tests.conftest import wait_for
from tests.system.groundstation import axe_check
from tests.system.groundstation.helpers import http, joules, start_groundstation

pytestmark = pytest.mark.system
VESSEL = "crew-boat"
ORIGIN = GeoOrigin(math.radians(47.3), math.radians(8.5), 400.0)
PATH_M = [(0.0, 0.0), (40.0, 0.0), (40.0, 30.0)]
POSITION_M = (10.0, 0.0)  # on the first leg: 30 m to P1, then 30 m to P2
HEADING_RAD = math.radians(30.0)
SOG_MPS = 1.2  # GNSS speed over ground


def number(text: str) -> float:
    m = re.search(r"-?\d+(?:\.\d+)?", text)
    assert m, f"no number in {text!r}"
    return float(m.group())


def test_the_vehicle_panel_reads_at_a_glance_and_commands_go_once(procs, zenoh_env, browser) -> None:
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    gs, base, token = start_groundstation(procs, zenoh_env)
    stop = threading.Event()
    mode_requests: list[str] = []

    def on_mode(req: ModeRequest) -> Reply:
        mode_requests.append(req.mode)
        time.sleep(1.0)  # a slow autopilot: a second click meanwhile must not send again
        return Reply.accept(1, f"mode {req.mode}")

    with Bus.open(VESSEL) as bus:
        bus.queryable(keys.MISSION_SET, lambda req: Reply.accept(1, "mission started"))
        bus.queryable(keys.VEHICLE_MODE, on_mode)
        bus.declare_alive("vehicle_io")
        pubs = {spec: bus.publisher(spec) for spec in (
            keys.NAV_ORIGIN, keys.NAV_STATE, keys.MISSION_STATUS, keys.VEHICLE_STATUS,
            keys.VEHICLE_BATTERY, keys.GNSS)}

        def publish() -> None:  # 5 Hz, as long as the test runs: nothing goes stale
            k = 0
            while not stop.wait(0.2):
                k += 1
                t = 1_700_000_000_000_000_000 + k * 200_000_000  # real time: Unix stamps [ns]
                pubs[keys.NAV_ORIGIN].put(NavOrigin.make(stamp_ns=t, lat_rad=ORIGIN.lat_rad,
                                                         lon_rad=ORIGIN.lon_rad, alt_m=ORIGIN.alt_m))
                pubs[keys.NAV_STATE].put(StateEstimate.make(
                    stamp_ns=t, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=POSITION_M[0],
                    y_m=POSITION_M[1], psi_rad=HEADING_RAD))
                pubs[keys.MISSION_STATUS].put(MissionStatus.make(
                    stamp_ns=t, state="active", mission_id="crew-box", active_leg=1,
                    waypoint_count=len(PATH_M), distance_to_waypoint_m=30.0, cross_track_m=0.1,
                    energy_used_j=45_600.0))
                pubs[keys.VEHICLE_STATUS].put(VehicleStatus.make(
                    stamp_ns=t, autopilot="ardupilot", link_ok=True, armed=True, mode="MANUAL",
                    battery_voltage_v=15.2, battery_remaining_frac=0.78))
                pubs[keys.VEHICLE_BATTERY].put(BatteryState.make(
                    stamp_ns=t, source="autopilot", voltage_v=15.21, remaining_frac=0.78,
                    remaining_j=210_600.0, reserve_j=50_000.0, capacity_j=270_000.0,
                    autopilot_level="low"))
                pubs[keys.GNSS].put(GnssFix.make(
                    stamp_ns=t, lat_rad=ORIGIN.lat_rad, lon_rad=ORIGIN.lon_rad, alt_m=400.0,
                    fix_type=3, vel_n_mps=SOG_MPS * math.cos(HEADING_RAD),
                    vel_e_mps=SOG_MPS * math.sin(HEADING_RAD), horizontal_std_m=0.8, satellites=12))

        publisher = threading.Thread(target=publish, daemon=True)
        publisher.start()
        try:
            wait_for(lambda: http("GET", base + f"api/vessels/{VESSEL}")[0] == 200, 30,
                     what=f"{VESSEL} seen by the ground station")
            status, body = http("POST", base + f"api/vessels/{VESSEL}/mission", token=token, body={
                "mission_id": "crew-box", "coa_radius_m": 2.0, "task_power_w": 250.0,
                "waypoints": [{"x_m": x, "y_m": y} for x, y in PATH_M]})
            assert status == 200, body

            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on("dialog", lambda d: d.accept())  # the page asks before moving the vessel
            page.goto(base)  # no token in the fragment: read-only
            page.wait_for_function("document.getElementById('v-mode').textContent === 'MANUAL'",
                                   timeout=60_000)
            page.wait_for_function("document.getElementById('p-eta').textContent.includes('s')",
                                   timeout=30_000)
            # Degrees once the fleet poll has brought the origin's scale (every 2 s).
            page.wait_for_function("document.getElementById('v-position').textContent.includes('°')",
                                   timeout=30_000)
            text = {i: page.locator(f"#{i}").text_content() or "" for i in (
                "v-battery", "v-energy-left", "v-gnss", "v-position", "v-heading", "v-speed",
                "v-time", "p-eta", "m-energy-used", "access")}
            # Battery: percent, voltage and the autopilot's own flag; energy left with the reserve.
            assert "78 %" in text["v-battery"] and "15.21 V" in text["v-battery"], text
            assert "low" in text["v-battery"]
            assert page.locator("#v-battery").get_attribute("class") == "warn"
            assert joules(text["v-energy-left"]) == pytest.approx(210_600.0, rel=0.005)
            assert "kJ" in text["v-energy-left"] and "Wh" in text["v-energy-left"]
            assert joules(text["v-energy-left"].split("reserve")[1]) == pytest.approx(50_000.0, rel=0.005)
            assert "3D" in text["v-gnss"] and "12" in text["v-gnss"] and "0.8" in text["v-gnss"]
            # Position in metres and degrees (the origin's latitude/longitude at N 10 m, E 0 m).
            lat, lon, _ = ORIGIN.to_geodetic(POSITION_M[0], POSITION_M[1], 0.0)
            m = re.search(r"N (-?[\d.]+) m, E (-?[\d.]+) m \((-?[\d.]+)°, (-?[\d.]+)°\)", text["v-position"])
            assert m, text["v-position"]
            assert (float(m.group(1)), float(m.group(2))) == POSITION_M
            assert float(m.group(3)) == pytest.approx(math.degrees(lat), abs=2e-6)
            assert float(m.group(4)) == pytest.approx(math.degrees(lon), abs=2e-6)
            assert number(text["v-heading"]) == pytest.approx(30.0, abs=0.5)
            assert number(text["v-speed"]) == pytest.approx(SOG_MPS, abs=0.005)  # the GNSS's
            assert "UTC" in text["v-time"]
            # ETA: 30 m to P1 and 30 m on to P2 at 1.2 m/s = 50 s.
            assert "60 m" in text["p-eta"] and "50 s" in text["p-eta"], text["p-eta"]
            assert joules(text["m-energy-used"]) == pytest.approx(45_600.0, rel=0.005)
            assert "kJ" in text["m-energy-used"]
            # The mode box shows the real mode, not a default HOLD.
            assert page.locator("#mode-select").input_value() == "MANUAL"
            assert text["access"] == "read-only"
            # WCAG A/AA by axe-core: no serious or critical violation (contrast among them).
            found = axe_check.violations(page, axe_script)
            print("\naxe-core:", [(v["id"], v["impact"], len(v["nodes"])) for v in found])
            assert not axe_check.serious(found), axe_check.serious(found)

            # With the token: operator; a double click on Set mode sends one request.
            page.evaluate(f"() => sessionStorage.setItem('seaway.groundstation.token', '{token}')")
            page.wait_for_function("document.getElementById('access').textContent === 'operator'",
                                   timeout=10_000)
            page.locator("#mode-select").fill("HOLD")
            sent: list[str] = []
            page.on("request", lambda r: sent.append(r.method) if r.url.endswith("/mode") else None)
            page.locator("button[data-cmd='mode']").dblclick()
            wait_for(lambda: mode_requests, 20, what="the mode request")
            page.wait_for_function("!document.querySelector(\"button[data-cmd='mode']\").disabled",
                                   timeout=20_000)
            page.wait_for_timeout(500)
            assert sent == ["POST"]  # the page sent one request for the double click
            assert mode_requests == ["HOLD"]
            # Sent: the box follows the real mode again (still MANUAL as published).
            page.wait_for_function("document.getElementById('mode-select').value === 'MANUAL'",
                                   timeout=10_000)
            assert not errors, errors
        finally:
            stop.set()
            publisher.join(5)
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
