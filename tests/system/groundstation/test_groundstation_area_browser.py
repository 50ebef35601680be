"""The operating area and the mission's reason on the operator's page in a real browser (Debian's
chromium driven by Playwright), issue #57: the real ``seaway-groundstation`` process on a real Zenoh
session, the test playing the vessel's controller and vehicle_io (publishing ``area/active``, a
mission waiting for the vehicle with its reason, and a vehicle status whose hold names the failsafe).

The page must draw the keep-in polygon, each keep-out polygon and circle and each rally point where
the area puts them (local NED metres through the map's own projection), and say in words why the
mission is not flying and which failsafe took the vessel.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    ActiveArea,
    AreaCircleZone,
    AreaPolygonZone,
    AreaRallyPoint,
    AreaVertex,
    MissionStatus,
    StateEstimate,
    VehicleStatus,
)
from seaway.runtime.bus import Bus

from tests.conftest import wait_for
from tests.system.groundstation import axe_check
from tests.system.groundstation.helpers import http, start_groundstation

pytestmark = pytest.mark.system
VESSEL = "area-boat"
KEEP_IN_M = [(-20.0, -20.0), (60.0, -20.0), (60.0, 40.0), (-20.0, 40.0)]
KEEP_OUT_M = [(20.0, 10.0), (30.0, 10.0), (25.0, 20.0)]
CIRCLE = (40.0, 0.0, 5.0)  # north, east, radius [m]
RALLY_M = (-10.0, 30.0)
WAITING = "waiting for the vehicle: the autopilot is in HOLD (battery failsafe)"


def area() -> ActiveArea:
    def zone(name: str, pts: list[tuple[float, float]]) -> AreaPolygonZone:
        return AreaPolygonZone(name=name, vertices=[AreaVertex(x_m=x, y_m=y) for x, y in pts])

    return ActiveArea.make(
        stamp_ns=1, since_ns=1, source="test", keep_in=zone("lake", KEEP_IN_M),
        keep_out_polygons=[zone("moorings", KEEP_OUT_M)],
        keep_out_circles=[AreaCircleZone(name="buoy", x_m=CIRCLE[0], y_m=CIRCLE[1], radius_m=CIRCLE[2])],
        rally_points=[AreaRallyPoint(name="jetty", x_m=RALLY_M[0], y_m=RALLY_M[1])])


def test_the_page_draws_the_operating_area_and_says_why_the_mission_waits(
        procs, zenoh_env, tmp_path, browser) -> None:
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    gs, base, _token = start_groundstation(procs, zenoh_env)
    stop = threading.Event()
    with Bus.open(VESSEL) as bus:  # the test plays the vessel's controller and vehicle_io
        bus.declare_alive("controller")
        pubs = {spec: bus.publisher(spec) for spec in (keys.NAV_STATE, keys.MISSION_STATUS,
                                                        keys.VEHICLE_STATUS, keys.AREA_ACTIVE)}

        def publish() -> None:  # 5 Hz, as long as the test runs: nothing goes stale
            k = 0
            while not stop.wait(0.2):
                k += 1
                t = k * 200_000_000  # [ns]
                pubs[keys.NAV_STATE].put(StateEstimate.make(stamp_ns=t, u_mps=0.0, v_mps=0.0,
                                                            r_radps=0.0, x_m=0.0, y_m=0.0, psi_rad=0.0))
                pubs[keys.MISSION_STATUS].put(MissionStatus.make(
                    stamp_ns=t, state="waiting", mission_id="m1", active_leg=1, waypoint_count=3,
                    reason=WAITING))
                pubs[keys.VEHICLE_STATUS].put(VehicleStatus.make(
                    stamp_ns=t, autopilot="ardupilot", link_ok=True, armed=True, mode="HOLD",
                    thrust_withheld="mode",
                    hold_reason="battery", hold_reason_detail="Battery 1 is low 11.00V used 500 mAh"))
                pubs[keys.AREA_ACTIVE].put(area().model_copy(update={"stamp_ns": t}))

        publisher = threading.Thread(target=publish, daemon=True)
        publisher.start()
        try:
            wait_for(lambda: http("GET", base + f"api/vessels/{VESSEL}")[0] == 200, 30,
                     what=f"{VESSEL} seen by the ground station")
            # The API carries the area as published.
            view = base + f"api/vessels/{VESSEL}"
            wait_for(lambda: (http("GET", view)[1].get("area") or {}).get("message"), 30,
                     what="the area in the vessel's view")
            served = http("GET", base + f"api/vessels/{VESSEL}")[1]["area"]["message"]
            assert [(v["x_m"], v["y_m"]) for v in served["keep_in"]["vertices"]] == KEEP_IN_M

            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(base)
            page.wait_for_selector(".area-keep-in", state="attached", timeout=60_000)
            page.evaluate("() => { const m = window.seaway.map; m.center = [20, 10]; m.scale = 6; "
                          "m.invalidate(); }")
            page.wait_for_timeout(500)
            drawn: dict[str, Any] = page.evaluate("""(w) => {
                const map = window.seaway.map;
                const pts = (el) => el.getAttribute('points').trim().split(/\\s+/)
                    .map((p) => p.split(',').map(Number));
                const keepIn = document.querySelector('.area-keep-in');
                const keepOut = document.querySelector('.area-keep-out');
                const circle = document.querySelector('.area-keep-out-circle');
                const rally = document.querySelector('.area-rally');
                const t = /translate\\(([-\\d.e]+),([-\\d.e]+)\\)/.exec(rally.getAttribute('transform'));
                return {
                    keepIn: pts(keepIn), keepInWorld: JSON.parse(keepIn.dataset.world),
                    keepOut: pts(keepOut), keepOutWorld: JSON.parse(keepOut.dataset.world),
                    circle: [Number(circle.getAttribute('cx')), Number(circle.getAttribute('cy')),
                             Number(circle.getAttribute('r'))],
                    rally: [Number(t[1]), Number(t[2])],
                    scale: map.scale,
                    project: {
                        keepIn: w.keepIn.map(([n, e]) => map.toScreen(n, e)),
                        keepOut: w.keepOut.map(([n, e]) => map.toScreen(n, e)),
                        circle: map.toScreen(w.circle[0], w.circle[1]),
                        rally: map.toScreen(w.rally[0], w.rally[1]),
                    },
                };
            }""", {"keepIn": KEEP_IN_M, "keepOut": KEEP_OUT_M, "circle": CIRCLE[:2], "rally": RALLY_M})
            assert drawn["keepInWorld"] == [list(p) for p in KEEP_IN_M]
            assert drawn["keepOutWorld"] == [list(p) for p in KEEP_OUT_M]
            for got, want in ((drawn["keepIn"], drawn["project"]["keepIn"]),
                              (drawn["keepOut"], drawn["project"]["keepOut"])):
                assert len(got) == len(want)
                for (gx, gy), (wx, wy) in zip(got, want, strict=True):
                    assert gx == pytest.approx(wx, abs=0.06) and gy == pytest.approx(wy, abs=0.06)
            assert drawn["circle"][0] == pytest.approx(drawn["project"]["circle"][0], abs=0.06)
            assert drawn["circle"][1] == pytest.approx(drawn["project"]["circle"][1], abs=0.06)
            assert drawn["circle"][2] == pytest.approx(CIRCLE[2] * drawn["scale"], abs=0.06)
            assert drawn["rally"][0] == pytest.approx(drawn["project"]["rally"][0], abs=0.06)
            assert drawn["rally"][1] == pytest.approx(drawn["project"]["rally"][1], abs=0.06)
            for sel in (".area-keep-in", ".area-keep-out", ".area-keep-out-circle", ".area-rally"):
                assert page.locator(sel).count() == 1, sel
            assert "jetty" in page.locator(".area-rally title").text_content()

            # Why the mission is not flying, and which failsafe took the vessel: in words.
            page.wait_for_function("document.getElementById('p-state').textContent === 'waiting'",
                                   timeout=30_000)
            assert page.locator("#p-reason").text_content() == WAITING
            assert page.locator("#p-reason").is_visible()
            failsafe = page.locator("#v-failsafe").text_content()
            assert "battery" in failsafe and "11.00V" in failsafe, failsafe
            # The warnings in this state (waiting, failsafe) meet WCAG AA too (axe-core).
            found = axe_check.violations(page, axe_script)
            assert not axe_check.serious(found), axe_check.serious(found)
            page.screenshot(path=str(tmp_path / "area.png"))
            print(f"\nscreenshot: {tmp_path / 'area.png'}")
            assert not errors, errors
        finally:
            stop.set()
            publisher.join(5)
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
