"""A fleet of two on the ground station's page, wide and in a phone's window (issue #59), in a real
browser (Debian's chromium driven by Playwright): the real ``seaway-groundstation`` process on a
real Zenoh session, the test playing both vessels' vehicle_io, estimator and controller.

Both vessels start on one spot. Shown and checked: each vessel labelled on the map in its own
colour, the labels apart; the other vessel's path and trail drawn; the fleet table (state, leg,
battery, link) and a click (in it or on the map) to pick a vessel; battery percent, the pause
reason and the real mode of the one picked. Guards: an action that moves or stops a vessel asks
first (declined: nothing sent), and a command from another tab or from a client without the page
shows as a note in the first tab. The map pans and zooms from the keyboard, the file inputs are in
the tab order, and at 390 x 844 the Live/Replay switch, the token button and the (folded) legend are
usable. axe-core finds no serious or critical WCAG A/AA violation at either size. Screenshots go to
the test's folder.
"""

from __future__ import annotations

import json
import math
import re
import signal
import threading

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    BatteryState,
    MissionCommand,
    MissionRequest,
    MissionStatus,
    NavOrigin,
    Reply,
    StateEstimate,
    VehicleStatus,
)
from seaway.runtime.bus import Bus
from seaway.tools.launch.address import ENV_TILES
from seaway.vessel.frames import GeoOrigin
from seaway_groundstation.routes.missions import AREA_NOT_SENT

from tests.conftest import BIN, wait_for
from tests.system.groundstation import axe_check
from tests.system.groundstation.helpers import http, pumped
from tests.unit.groundstation import mbtiles_maker

pytestmark = pytest.mark.system
A, B = "vessel1", "vessel2"
ORIGIN = GeoOrigin(math.radians(47.3), math.radians(8.5), 400.0)
PAUSE_REASON = "paused by the operator at leg 1"
BATTERY = {A: 0.78, B: 0.41}
MODE = {A: "HOLD", B: "MANUAL"}
B_PATH_M = [(0.0, 0.0), (0.0, 30.0), (20.0, 30.0)]


def boxes_overlap(a: dict, b: dict) -> bool:
    return (a["x"] < b["x"] + b["width"] and b["x"] < a["x"] + a["width"]
            and a["y"] < b["y"] + b["height"] and b["y"] < a["y"] + a["height"])


@pytest.mark.slow  # a browser, two pages, about 30 s
def test_a_fleet_of_two_is_told_apart_guarded_and_usable_on_a_phone(procs, zenoh_env, browser,
                                                                     tmp_path) -> None:
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    shots = tmp_path / "screenshots"
    shots.mkdir()
    print(f"\nscreenshots: {shots}")
    # Offline map tiles as the launcher hands them over (its --tiles, in the environment): a tiny
    # MBTiles file around the origin, served by the ground station itself.
    lat0, lon0 = math.degrees(ORIGIN.lat_rad), math.degrees(ORIGIN.lon_rad)
    around = [(z, x + dx, y + dy) for z in range(15, 21)
              for x, y in [mbtiles_maker.slippy(lat0, lon0, z)] for dx in range(-6, 7) for dy in range(-6, 7)]
    tiles = mbtiles_maker.make(tmp_path / "lake.mbtiles", around)
    gs = procs.start([str(BIN / "seaway-groundstation"), "--port", "0", "--request-timeout-s", "10"],
                     {**zenoh_env, ENV_TILES: str(tiles)}, "groundstation")
    line = wait_for(lambda: re.search(r"groundstation: (http://127\.0\.0\.1:\d+/) token (\S+)",
                                      procs.log(gs)), 60, what="the ground station's address line")
    base, token = line.group(1), line.group(2)
    stop = threading.Event()
    commands: dict[str, list[str]] = {A: [], B: []}
    missions: dict[str, list[MissionRequest]] = {A: [], B: []}

    def on_mission(vessel: str):
        def serve(req: MissionRequest) -> Reply:
            missions[vessel].append(req)
            return Reply.accept(1, "mission started")
        return serve

    def on_command(vessel: str):
        def serve(req: MissionCommand) -> Reply:
            commands[vessel].append(req.command)
            return Reply.accept(1, req.command)
        return serve

    with Bus.open(A) as bus:
        for v in (A, B):
            bus.queryable(keys.MISSION_SET, on_mission(v), vessel=v)
            bus.queryable(keys.MISSION_COMMAND, on_command(v), vessel=v)
            bus.queryable(keys.VEHICLE_MODE, lambda req: Reply.accept(1, f"mode {req.mode}"), vessel=v)
            bus.declare_alive("vehicle_io", vessel=v)
        pubs = {(spec, v): bus.publisher(spec, vessel=v) for v in (A, B) for spec in (
            keys.NAV_ORIGIN, keys.NAV_STATE, keys.MISSION_STATUS, keys.VEHICLE_STATUS,
            keys.VEHICLE_BATTERY)}

        def publish() -> None:  # 5 Hz: A holds on the start, B leaves it eastwards at 1 m/s
            k = 0
            while not stop.wait(0.2):
                k += 1
                t = 1_700_000_000_000_000_000 + k * 200_000_000
                east_b = min(0.2 * k, 30.0)
                for v, east, mission in (
                        (A, 0.0, MissionStatus.make(stamp_ns=t, state="paused", mission_id="a-box",
                                                    active_leg=1, waypoint_count=3,
                                                    reason=PAUSE_REASON)),
                        (B, east_b, MissionStatus.make(stamp_ns=t, state="active", mission_id="b-line",
                                                       active_leg=1, waypoint_count=3,
                                                       distance_to_waypoint_m=30.0 - east_b))):
                    pubs[(keys.NAV_ORIGIN, v)].put(NavOrigin.make(
                        stamp_ns=t, lat_rad=ORIGIN.lat_rad, lon_rad=ORIGIN.lon_rad, alt_m=ORIGIN.alt_m))
                    pubs[(keys.NAV_STATE, v)].put(StateEstimate.make(
                        stamp_ns=t, u_mps=1.0 if v == B else 0.0, v_mps=0.0, r_radps=0.0, x_m=0.0,
                        y_m=east, psi_rad=math.pi / 2 if v == B else 0.0))
                    pubs[(keys.MISSION_STATUS, v)].put(mission)
                    pubs[(keys.VEHICLE_STATUS, v)].put(VehicleStatus.make(
                        stamp_ns=t, autopilot="px4", link_ok=True, armed=True, mode=MODE[v],
                        battery_voltage_v=15.0, battery_remaining_frac=BATTERY[v]))
                    pubs[(keys.VEHICLE_BATTERY, v)].put(BatteryState.make(
                        stamp_ns=t, source="autopilot", voltage_v=15.0, remaining_frac=BATTERY[v],
                        remaining_j=BATTERY[v] * 270_000.0, reserve_j=50_000.0, capacity_j=270_000.0))

        publisher = threading.Thread(target=publish, daemon=True)
        publisher.start()
        try:
            for v in (A, B):
                wait_for(lambda v=v: http("GET", base + f"api/vessels/{v}")[0] == 200, 30,
                         what=f"{v} seen by the ground station")
            status, body = http("POST", base + f"api/vessels/{B}/mission", token=token, body={
                "mission_id": "b-line", "coa_radius_m": 2.0, "task_power_w": 250.0,
                "waypoints": [{"x_m": x, "y_m": y} for x, y in B_PATH_M]})
            assert status == 200, body

            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(base + f"#token={token}")
            page.wait_for_function("document.querySelectorAll('#fleet-table tbody tr').length === 2",
                                   timeout=60_000)
            page.locator(f"#fleet-table button.pick:text-is('{A}')").click()
            page.wait_for_function(f"document.getElementById('v-mode').textContent === '{MODE[A]}'",
                                   timeout=30_000)
            # The picked vessel as the crew reads it: battery percent, the pause reason, the real mode.
            assert "78 %" in page.locator("#v-battery").text_content()
            assert page.locator("#p-state").text_content() == "paused"
            assert page.locator("#p-reason").text_content() == PAUSE_REASON
            assert page.locator("#mode-select").input_value() == MODE[A]
            # The fleet table: state, leg, battery and link of each.
            page.wait_for_function(f"document.querySelector('#fleet-table tr[data-vessel={B}]')"
                                   ".textContent.includes('41 %')", timeout=30_000)
            rows = {v: page.locator(f"#fleet-table tr[data-vessel={v}]").inner_text() for v in (A, B)}
            assert "paused" in rows[A] and "78 %" in rows[A] and "1 / 2" in rows[A] and "up" in rows[A], rows
            assert "active" in rows[B] and "41 %" in rows[B] and "up" in rows[B], rows
            # Both labelled, each in its own colour, the labels apart though both started on one
            # spot; the other vessel's path and trail drawn.
            page.wait_for_selector(f".other-trail[data-vessel={B}]", state="attached", timeout=30_000)
            page.wait_for_selector(f".other-path[data-vessel={B}]", state="attached", timeout=30_000)
            page.evaluate("() => window.seaway.map.fit()")
            labels = {v: page.locator(f".vessel-label[data-vessel={v}]") for v in (A, B)}
            for v in (A, B):
                assert labels[v].text_content() == v
            colours = {v: labels[v].locator("text").get_attribute("fill") for v in (A, B)}
            assert colours[A] != colours[B], colours
            # (both boxes read at once: the map redraws its labels ten times a second)
            boxes = page.evaluate("(names) => names.map((n) => document.querySelector("
                                  "`.vessel-label[data-vessel=${n}] rect`).getBoundingClientRect().toJSON())",
                                  [A, B])
            assert not boxes_overlap(*boxes), boxes
            # The MBTiles' tiles under the grid, each one the ground station serves.
            page.wait_for_selector(".layer-tiles image", state="attached", timeout=30_000)
            served = page.evaluate("""async () => {
                const hrefs = [...document.querySelectorAll('.layer-tiles image')]
                    .map((i) => i.getAttribute('href'));
                const r = await fetch(hrefs[0]);
                return [hrefs.length, hrefs[0], r.status, r.headers.get('content-type')];
            }""")
            assert served[0] >= 1 and served[1].startswith("/tiles/"), served
            assert served[2:] == [200, "image/png"], served
            page.screenshot(path=str(shots / "1-fleet-wide.png"))
            found = axe_check.violations(page, axe_script)
            print("axe-core, wide:", [(v["id"], v["impact"], len(v["nodes"])) for v in found])
            assert not axe_check.serious(found), axe_check.serious(found)
            # Nothing dropped (two vessels, room for 64): the fleet panel says nothing of it.
            assert page.evaluate("() => window.seaway.app.fleetCounts.refused") == 0
            assert page.locator("#fleet-notice").is_hidden()

            # A click on the other vessel on the map picks it.
            page.wait_for_function(f"document.querySelector('.vessel-glyph.other[data-vessel={B}]')",
                                   timeout=10_000)
            page.wait_for_function("window.seaway.app.live.vessels.get('vessel2')"
                                   ".message('state').y_m > 4", timeout=30_000)
            page.evaluate("() => window.seaway.map.fit()")
            page.wait_for_timeout(300)
            page.locator(f".vessel-glyph.other[data-vessel={B}]").click()
            page.wait_for_function(f"document.getElementById('v-mode').textContent === '{MODE[B]}'",
                                   timeout=10_000)
            assert "41 %" in page.locator("#v-battery").text_content()
            assert page.locator(f"#fleet-table tr[data-vessel={B}]").get_attribute("class") == "selected"

            # The keyboard: the map pans and zooms when focused, with a visible focus ring.
            page.locator("#map").focus()
            centre = page.evaluate("() => [...window.seaway.map.center]")
            scale = page.evaluate("() => window.seaway.map.scale")
            page.keyboard.press("ArrowRight")
            page.keyboard.press("+")
            assert page.evaluate("() => window.seaway.map.center[1]") > centre[1]
            assert page.evaluate("() => window.seaway.map.scale") > scale
            ring = page.evaluate("() => getComputedStyle(document.getElementById('map')).outlineStyle")
            assert ring != "none", ring
            # The file input is in the tab order: Tab from the button before it reaches it.
            page.locator("#draft-from-active").focus()
            page.keyboard.press("Tab")
            assert page.evaluate("() => document.activeElement.id") == "import-file"

            # Per-waypoint speed: a GeoJSON's speeds_mps in the editor, editable; the first speed is
            # sent as the mission's speed hint (the controller takes one per mission).
            # The file also carries a keep-out circle: the page says it is not sent.
            line = [[lon0 + k * 1e-4, lat0] for k in range(3)]
            doc = {"type": "FeatureCollection", "features": [
                {"type": "Feature", "geometry": {"type": "LineString", "coordinates": line},
                 "properties": {"speeds_mps": [None, 1.3, 0.9]}},
                {"type": "Feature", "geometry": {"type": "Point", "coordinates": [lon0, lat0 + 5e-4]},
                 "properties": {"area": "keep_out", "radius_m": 5.0}}]}
            page.set_input_files("#import-file", files=[{
                "name": "speeds.geojson", "mimeType": "application/json",
                "buffer": json.dumps(doc).encode()}])
            page.wait_for_function("document.querySelectorAll('#wp-table tbody tr').length === 3",
                                   timeout=10_000)
            assert page.locator("#messages .msg", has_text=AREA_NOT_SENT).count() == 1
            speeds = [page.locator(f"#wp-table input[aria-label^='speed {i}']").input_value()
                      for i in range(3)]
            assert speeds == ["", "1.3", "0.9"], speeds
            page.locator("#wp-table input[aria-label^='speed 0']").fill("1.1")
            page.locator("#wp-table input[aria-label^='speed 0']").press("Tab")
            def accept(d) -> None:
                d.accept()
            page.on("dialog", accept)  # every confirmation accepted: a double click sends once
            page.locator("#send-mission").dblclick()
            # The page checks the mission first, then asks: the dialog comes after an await.
            pumped(page, lambda: len(missions[B]) == 2, "the mission with its speed hint")
            page.wait_for_function("!document.getElementById('send-mission').disabled", timeout=20_000)
            page.wait_for_timeout(500)
            assert len(missions[B]) == 2
            page.remove_listener("dialog", accept)
            assert missions[B][-1].speed_hint_mps == pytest.approx(1.1)
            assert len(missions[B][-1].waypoints) == 3

            # Guards: a second tab. Declining the confirmation sends nothing; accepting sends once.
            other = browser.new_page(viewport={"width": 1200, "height": 900})
            other.on("pageerror", lambda e: errors.append(str(e)))
            other.goto(base + f"#token={token}")
            other.wait_for_function("document.querySelectorAll('#fleet-table tbody tr').length === 2",
                                    timeout=60_000)
            other.locator(f"#fleet-table button.pick:text-is('{B}')").click()
            other.wait_for_function(f"document.getElementById('v-mode').textContent === '{MODE[B]}'",
                                    timeout=30_000)
            asked: list[str] = []
            other.once("dialog", lambda d: (asked.append(d.message), d.dismiss()))
            other.locator("button[data-cmd='pause']").click()
            other.wait_for_function("!document.querySelector(\"button[data-cmd='pause']\").disabled")
            assert asked and "Pause" in asked[0] and B in asked[0], asked
            other.wait_for_timeout(500)
            assert commands[B] == []  # declined: not sent
            other.once("dialog", lambda d: d.accept())
            other.locator("button[data-cmd='pause']").click()
            wait_for(lambda: commands[B] == ["pause"], 20, what="the pause request")
            # The first tab is told, as a note and in its vehicle panel.
            page.wait_for_function(f"[...document.querySelectorAll('#messages .msg')].some((m) => "
                                   f"m.textContent.includes('{B}: pause sent by another tab or client'))",
                                   timeout=20_000)
            page.wait_for_function("document.getElementById('v-last-command').textContent"
                                   ".includes('pause — accepted')", timeout=10_000)
            # ... and so is the tab that sent it of nothing "from another" about its own.
            other.wait_for_function("document.getElementById('v-last-command').textContent"
                                    ".includes('pause — accepted')", timeout=10_000)
            assert "another" not in other.locator("#v-last-command").text_content()
            assert not other.locator("#messages .msg", has_text="another tab").count()
            # A client without a page (the API with the token): every tab notes it too.
            status, body = http("POST", base + f"api/vessels/{B}/mode", {"mode": "HOLD"}, token=token)
            assert status == 200, body
            for p in (page, other):
                p.wait_for_function(f"[...document.querySelectorAll('#messages .msg')].some((m) => m"
                                    f".textContent.includes('{B}: mode HOLD sent by another tab or client'))",
                                    timeout=20_000)
            page.screenshot(path=str(shots / "2-fleet-note.png"))
            other.close()

            # A phone's window: the switch, the token button and the legend usable.
            phone = browser.new_page(viewport={"width": 390, "height": 844})
            phone.on("pageerror", lambda e: errors.append(str(e)))
            phone.goto(base)
            phone.wait_for_function("document.querySelectorAll('#fleet-table tbody tr').length === 2",
                                    timeout=60_000)
            for sel in ("#mode-live", "#mode-replay", "#token-button", "#vessel-picker"):
                box = phone.locator(sel).bounding_box()
                assert box["width"] >= 40 and box["height"] >= 24, (sel, box)
                assert box["x"] >= 0 and box["x"] + box["width"] <= 390, (sel, box)
            assert phone.evaluate("() => document.documentElement.scrollWidth") <= 390
            legend = phone.locator("#map-legend")
            assert legend.get_attribute("open") is None  # folded: the vessel stays in sight
            phone.wait_for_selector("#vessel-glyph", timeout=30_000)
            phone.evaluate("() => window.seaway.map.fit()")
            phone.wait_for_timeout(300)
            boxes = phone.evaluate("() => ['map-legend', 'vessel-glyph'].map((i) => "
                                   "document.getElementById(i).getBoundingClientRect().toJSON())")
            assert not boxes_overlap(*boxes), boxes
            phone.locator("#map-legend summary").click()
            assert legend.get_attribute("open") is not None
            assert phone.locator(".lg.trail").is_visible()
            phone.locator("#map-legend summary").click()
            phone.locator("#token-button").click()
            assert phone.locator("#token-dialog").is_visible()
            box = phone.locator("#token-input").bounding_box()
            assert box["x"] >= 0 and box["x"] + box["width"] <= 390, box
            phone.keyboard.press("Escape")
            phone.locator("#mode-replay").click()
            assert phone.locator("#replay-panel").is_visible()
            phone.locator("#mode-live").click()
            phone.screenshot(path=str(shots / "3-phone.png"), full_page=True)
            found = axe_check.violations(phone, axe_script)
            print("axe-core, 390 px:", [(v["id"], v["impact"], len(v["nodes"])) for v in found])
            assert not axe_check.serious(found), axe_check.serious(found)
            assert not errors, errors
        finally:
            stop.set()
            publisher.join(5)
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
