"""The page says when the ground station drops vessels, in a real browser (Debian's chromium driven
by Playwright): the real ``seaway-groundstation`` process, started to keep at most two vessels
(``max_vessels`` in its ``--config`` file), on a real Zenoh session where the test plays two
vessels, then publishes states under more names than there is room for.

Checked: nothing is said while nothing was dropped; then the fleet panel's notice shows the number
of messages the ground station dropped (the same number as ``GET /api/vessels``) and the most it
keeps, and follows that number as it grows; it is not shown in the replay view; axe-core finds no
violation on the page with the notice that it did not find without it, and none serious.

A second test forgets vessels for real: a station keeping one vessel, which forgets a vessel with no
service's health token once it has been silent ``forget_after_s`` (1 s here), takes each new name in
turn; the page, 390 px wide, counts them.
"""

from __future__ import annotations

import re
import signal
import threading

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionStatus, StateEstimate, VehicleStatus
from seaway.runtime.bus import Bus

from tests.conftest import wait_for
from tests.system.groundstation import axe_check
from tests.system.groundstation.helpers import http, start_groundstation

pytestmark = pytest.mark.system
MAX_VESSELS = 2
FLEET = ("vessel1", "vessel2")
EXTRA = ("stray1", "stray2", "stray3")
NOTICE_NUMBER = "(id) => Number(document.getElementById(id)?.textContent)"


def state(k: int, east_m: float = 0.0) -> StateEstimate:
    return StateEstimate.make(stamp_ns=k * 200_000_000, u_mps=0.0, v_mps=0.0, r_radps=0.0, x_m=0.0,
                              y_m=east_m, psi_rad=0.0)


def test_the_page_says_how_many_messages_the_full_ground_station_dropped(
        procs, zenoh_env, tmp_path, browser) -> None:
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    config = tmp_path / "groundstation.toml"
    config.write_text(f"max_vessels = {MAX_VESSELS}\n")
    gs, base, _token = start_groundstation(procs, zenoh_env, "--config", str(config))

    def refused() -> int:
        status, body = http("GET", base + "api/vessels")
        assert status == 200, body
        assert body["max_vessels"] == MAX_VESSELS, body
        return body["vessels_refused"]

    stop = threading.Event()
    with Bus.open(FLEET[0]) as bus:
        for v in FLEET:  # alive: never forgotten to make room
            bus.declare_alive("vehicle_io", vessel=v)
        pubs = {v: bus.publisher(keys.NAV_STATE, vessel=v) for v in FLEET + EXTRA}
        others = {(spec, v): bus.publisher(spec, vessel=v)
                  for spec in (keys.MISSION_STATUS, keys.VEHICLE_STATUS) for v in FLEET}

        def publish() -> None:  # the fleet at 5 Hz, as long as the test runs: nothing stale (dimmed)
            k = 0
            while not stop.wait(0.2):
                k += 1
                t = k * 200_000_000
                for i, v in enumerate(FLEET):
                    pubs[v].put(state(k, 5.0 * i))
                    others[(keys.MISSION_STATUS, v)].put(MissionStatus.make(stamp_ns=t, state="idle"))
                    others[(keys.VEHICLE_STATUS, v)].put(VehicleStatus.make(
                        stamp_ns=t, autopilot="px4", link_ok=True, armed=False, mode="HOLD"))

        publisher = threading.Thread(target=publish, daemon=True)
        publisher.start()
        try:
            for v in FLEET:
                wait_for(lambda v=v: http("GET", base + f"api/vessels/{v}")[0] == 200, 30,
                         what=f"{v} seen by the ground station")
            assert refused() == 0

            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(base)
            page.wait_for_function("document.querySelectorAll('#fleet-table tbody tr').length === 2",
                                   timeout=60_000)
            page.wait_for_function("window.seaway.app.fleetCounts !== null", timeout=10_000)
            page.wait_for_timeout(500)  # a render after the fleet view was read
            assert page.locator("#fleet-notice").is_hidden()
            assert page.locator("#fleet-refused").count() == 0
            before = axe_check.violations(page, axe_script)
            print("axe-core, nothing dropped:", [(v["id"], v["impact"], len(v["nodes"])) for v in before])

            # Three more names than there is room for: each of their messages is dropped.
            for k in range(1, 5):
                for v in EXTRA:
                    pubs[v].put(state(k))
            wait_for(lambda: refused() >= len(EXTRA) * 4, 30, what="the strays' messages refused")
            count = refused()
            assert count == len(EXTRA) * 4, count
            page.wait_for_function(f"({NOTICE_NUMBER})('fleet-refused') === {count}", timeout=10_000)
            notice = page.locator("#fleet-notice")
            assert notice.is_visible()
            assert notice.get_attribute("role") == "status"
            assert re.search(rf"\b{MAX_VESSELS}\b", notice.inner_text()), notice.inner_text()
            assert page.locator("#fleet-forgotten").count() == 0  # none forgotten: not said
            assert http("GET", base + "api/vessels")[1]["vessels_forgotten"] == 0
            # The fleet is still the first two; the strays are nowhere on the page.
            assert page.locator("#fleet-table tbody tr").count() == 2
            assert not any(page.locator(f"#fleet-table tr[data-vessel={v}]").count() for v in EXTRA)
            page.screenshot(path=str(tmp_path / "refused.png"))
            after = axe_check.violations(page, axe_script)
            print("axe-core, dropped shown:", [(v["id"], v["impact"], len(v["nodes"])) for v in after])
            assert not axe_check.serious(after), axe_check.serious(after)
            new = {v["id"] for v in after} - {v["id"] for v in before}
            assert not new, [v for v in after if v["id"] in new]

            # More of them: the notice follows the count.
            for v in EXTRA:
                pubs[v].put(state(9))
            wait_for(lambda: refused() >= count + len(EXTRA), 30, what="more refused")
            count = refused()
            page.wait_for_function(f"({NOTICE_NUMBER})('fleet-refused') === {count}", timeout=10_000)

            # The replay view is not the live station's: no notice there.
            page.locator("#mode-replay").click()
            page.wait_for_function("document.getElementById('fleet-notice').hidden", timeout=5_000)
            page.locator("#mode-live").click()
            page.wait_for_function("!document.getElementById('fleet-notice').hidden", timeout=5_000)

            assert not errors, errors
        finally:
            stop.set()
            publisher.join(5)
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)


def test_the_page_counts_the_vessels_a_full_ground_station_forgot(procs, zenoh_env, tmp_path,
                                                                   browser) -> None:
    """Room for one vessel, and a vessel silent for 1 s with no service's health token may be
    forgotten for a new name: three names one after the other, each silent before the next."""
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    config = tmp_path / "groundstation.toml"
    config.write_text("max_vessels = 1\nforget_after_s = 1.0\n")
    gs, base, _token = start_groundstation(procs, zenoh_env, "--config", str(config))

    def fleet() -> dict:
        status, body = http("GET", base + "api/vessels")
        assert status == 200, body
        return body

    names = ("ghost1", "ghost2", "ghost3")
    with Bus.open(names[0]) as bus:
        page = browser.new_page(viewport={"width": 390, "height": 844})
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(base)
        for k, name in enumerate(names):
            pub = bus.publisher(keys.NAV_STATE, vessel=name)
            # Each name is taken once the one before has been silent long enough (the first at
            # once): published until the ground station lists it.
            wait_for(lambda pub=pub, name=name, k=k: pub.put(state(k + 1)) is None and [
                v["vessel"] for v in fleet()["vessels"]] == [name], 30,
                what=f"{name} taking the place of the vessel before it")
        forgotten = fleet()["vessels_forgotten"]
        # Each name forgot the one before (and the first, any vessel the station held before it).
        assert forgotten >= len(names) - 1, forgotten
        page.wait_for_function(f"({NOTICE_NUMBER})('fleet-forgotten') === {forgotten}",
                               timeout=30_000)
        assert page.locator("#fleet-notice").is_visible()
        assert page.evaluate("() => document.documentElement.scrollWidth") <= 390
        page.screenshot(path=str(tmp_path / "forgotten-phone.png"), full_page=True)
        found = axe_check.violations(page, axe_script)
        print("axe-core, 390 px, forgotten:", [(v["id"], v["impact"], len(v["nodes"])) for v in found])
        assert not axe_check.serious(found), axe_check.serious(found)
        assert not errors, errors
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
