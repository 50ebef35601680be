"""The energy budget on the operator's page in a real browser (Debian's chromium driven by
Playwright), issue #17 item 5: the real ``seaway-groundstation`` process on a real Zenoh session,
the test playing the vessel's controller (accepting the mission the page's API sends, publishing
its state, status and ``mission/energy``). The page must show the budget's figures as published,
the point of no return as a marker on the mission's path where the budget puts it (local NED, and
its latitude/longitude through the published origin), and the decision prominently once taken.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import signal
import threading
from pathlib import Path
from typing import Any

import pytest
from seaway.contract import keys
from seaway.contract.messages import EnergyBudget, MissionStatus, NavOrigin, Reply, StateEstimate
from seaway.runtime.bus import Bus
from seaway.vessel.frames import GeoOrigin

from tests.conftest import wait_for
from tests.system.groundstation.helpers import http, joules, start_groundstation

pytestmark = pytest.mark.system
VESSEL = "energy-boat"
PATH_M = [(0.0, 0.0), (40.0, 0.0), (40.0, 20.0)]
NO_RETURN_M = (30.0, 0.0)  # on the first leg, 20 m ahead of the vessel
ORIGIN = GeoOrigin(math.radians(47.3), math.radians(8.5), 400.0)
REASON = "energy to get home 4200 J + reserve 1000 J reached the battery's 5200 J left"


def budget(decided: bool) -> EnergyBudget:
    return EnergyBudget.make(
        stamp_ns=1, mission_id="energy-box", active_leg=1, energy_used_j=1234.5,
        energy_to_go_j=6789.0, energy_to_go_low_j=6500.0, energy_to_go_high_j=7100.0,
        energy_to_home_j=4200.0, energy_to_home_low_j=4000.0, energy_to_home_high_j=4400.0,
        home_x_m=0.0, home_y_m=0.0, battery_remaining_j=5200.0 if decided else 9000.0,
        reserve_j=1000.0, margin_j=0.0 if decided else 3800.0,
        no_return_x_m=None if decided else NO_RETURN_M[0],
        no_return_y_m=None if decided else NO_RETURN_M[1],
        no_return_along_m=None if decided else 20.0, policy="return",
        decision="return" if decided else "none", decided_ns=5 if decided else None,
        reason=REASON if decided else "")


def test_the_page_shows_the_energy_budget_the_point_of_no_return_and_the_decision(
        procs, zenoh_env, tmp_path, browser) -> None:
    gs, base, token = start_groundstation(procs, zenoh_env)
    decided = threading.Event()
    stop = threading.Event()
    with Bus.open(VESSEL) as bus:  # the test plays the vessel's controller
        bus.queryable(keys.MISSION_SET, lambda req: Reply.accept(1, "mission started"))
        bus.declare_alive("controller")
        pubs = {spec: bus.publisher(spec) for spec in (keys.NAV_ORIGIN, keys.NAV_STATE,
                                                        keys.MISSION_STATUS, keys.MISSION_ENERGY)}

        def publish() -> None:  # 5 Hz, as long as the test runs: nothing goes stale
            k = 0
            while not stop.wait(0.2):
                k += 1
                t = k * 200_000_000  # [ns]: 5 Hz
                pubs[keys.NAV_ORIGIN].put(NavOrigin.make(stamp_ns=t, lat_rad=ORIGIN.lat_rad,
                                                         lon_rad=ORIGIN.lon_rad, alt_m=ORIGIN.alt_m))
                pubs[keys.NAV_STATE].put(StateEstimate.make(stamp_ns=t, u_mps=1.0, v_mps=0.0,
                                                            r_radps=0.0, x_m=10.0, y_m=0.0, psi_rad=0.0))
                pubs[keys.MISSION_STATUS].put(MissionStatus.make(
                    stamp_ns=t, state="active", mission_id="energy-box", active_leg=1,
                    waypoint_count=len(PATH_M), energy_used_j=1234.5, energy_to_go_j=6789.0))
                pubs[keys.MISSION_ENERGY].put(budget(decided.is_set()).model_copy(update={"stamp_ns": t}))

        publisher = threading.Thread(target=publish, daemon=True)
        publisher.start()
        try:
            wait_for(lambda: http("GET", base + f"api/vessels/{VESSEL}")[0] == 200, 30,
                     what=f"{VESSEL} seen by the ground station")
            # The mission as the page's API sends it: the ground station then knows its path.
            status, body = http("POST", base + f"api/vessels/{VESSEL}/mission", token=token, body={
                "mission_id": "energy-box", "coa_radius_m": 2.0, "task_power_w": 250.0,
                "waypoints": [{"x_m": x, "y_m": y} for x, y in PATH_M]})
            assert status == 200, body

            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(base)
            page.wait_for_function("document.getElementById('e-source').textContent === 'mission/energy'",
                                   timeout=60_000)
            # The map draws the mission flown (the fleet poll) before the marker is checked on it.
            page.wait_for_function("window.seaway.map.model.plan?.mission_id === 'energy-box'",
                                   timeout=30_000)
            page.evaluate("() => window.seaway.map.fit()")
            page.wait_for_timeout(500)
            text = {i: page.locator(f"#{i}").text_content() for i in (
                "m-energy-used", "e-finish", "e-home", "e-battery", "e-reserve", "e-margin", "e-pnr",
                "e-decision")}
            # Energies in kJ with Wh, three significant digits; a band as its ends in the same unit.
            assert text["m-energy-used"] == "1.23 kJ (0.34 Wh)"
            assert text["e-finish"] == "6.79 kJ (1.89 Wh), 6.50–7.10 kJ"
            assert text["e-home"] == "4.20 kJ (1.17 Wh), 4.00–4.40 kJ"
            assert (text["e-battery"], text["e-reserve"], text["e-margin"]) == (
                "9.00 kJ (2.50 Wh)", "1.00 kJ (0.28 Wh)", "3.80 kJ (1.06 Wh)")
            assert text["e-decision"] == "none (policy: return)"
            assert not page.locator("#map-decision").is_visible()
            # The point of no return: in metres on the map's path, in degrees through the origin.
            lat, lon, _ = ORIGIN.to_geodetic(*NO_RETURN_M, 0.0)
            m = re.fullmatch(r"in 20\.0 m, at N 30\.0 E 0\.0 m \((-?[\d.]+)°, (-?[\d.]+)°\)", text["e-pnr"])
            assert m, text["e-pnr"]
            assert float(m.group(1)) == pytest.approx(math.degrees(lat), abs=2e-6)
            assert float(m.group(2)) == pytest.approx(math.degrees(lon), abs=2e-6)
            marker: dict[str, Any] = page.evaluate("""() => {
                const g = document.getElementById('no-return-marker');
                const m = /translate\\(([-\\d.e]+),([-\\d.e]+)\\)/.exec(g.getAttribute('transform'));
                const on = window.seaway.map.toScreen(30, 0);
                return {x: Number(m[1]), y: Number(m[2]), sx: on[0], sy: on[1],
                        n: Number(g.dataset.n), e: Number(g.dataset.e)};
            }""")
            assert (marker["n"], marker["e"]) == NO_RETURN_M
            assert marker["x"] == pytest.approx(marker["sx"], abs=0.01)
            assert marker["y"] == pytest.approx(marker["sy"], abs=0.01)
            assert page.locator("#no-return-marker").is_visible()
            assert page.locator("#home-marker").is_visible()
            page.screenshot(path=str(tmp_path / "energy-1-budget.png"))
            page.locator("#energy-panel").screenshot(path=str(tmp_path / "energy-1-panel.png"))

            # The decision: on the map and in the panel, with the controller's reason.
            decided.set()
            page.wait_for_selector("#map-decision", state="visible", timeout=30_000)
            assert page.locator("#map-decision").text_content() == f"RETURNING HOME — {REASON}"
            assert page.locator("#e-decision-banner").is_visible()
            assert page.locator("#e-decision").text_content() == "RETURNING HOME (policy: return)"
            assert joules(page.locator("#e-margin").text_content()) == 0.0
            assert page.locator("#e-pnr").text_content() == "reached: the margin is gone"
            page.wait_for_selector("#no-return-marker", state="detached", timeout=10_000)
            page.screenshot(path=str(tmp_path / "energy-2-decided.png"))
            page.locator("#energy-panel").screenshot(path=str(tmp_path / "energy-2-panel.png"))
            print(f"\nscreenshots: {tmp_path}")
            assert not errors, errors
        finally:
            stop.set()
            publisher.join(5)
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
    keep = os.environ.get("SEAWAY_KEEP_SCREENSHOTS")
    if keep:  # docs/groundstation/8-energy-*.png: SEAWAY_KEEP_SCREENSHOTS=docs/groundstation
        Path(keep).mkdir(parents=True, exist_ok=True)
        for name in ("energy-1-budget.png", "energy-2-decided.png", "energy-2-panel.png"):
            shutil.copy(tmp_path / name, Path(keep) / f"8-{name}")
