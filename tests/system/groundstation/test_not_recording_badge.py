"""NOT RECORDING on the page, in a real browser (Debian's chromium driven by Playwright): the real
``seaway-groundstation`` process on a real Zenoh session, the test playing a vessel's estimator and
controller (their health tokens) and, on a Zenoh session of its own as the real one has, its
recorder.

The launcher keeps a real-time run flying when its recorder fails for good, so a crew must see at a
glance when a vessel runs unrecorded. With the recorder's token present the page shows no alarm;
once the recorder's session is gone (its token withdrawn) an alarm saying the vessel is not recording
shows within a few seconds, in a live region (screen readers hear it), in view without scrolling,
at full opacity, and axe-core finds no serious or critical WCAG A/AA violation on the page; once a
recorder declares its token again the alarm goes.

In a fleet the crew sees which vessels are unrecorded, not only the one picked: of two vessels, both
with an estimator and a controller and only one with a recorder, the fleet table marks the other's
row (and only it) as not recording, at full opacity, axe-core finding no serious or critical
violation; once that vessel's recorder declares its token the mark goes.

On a shore computer the page also hears the shore's own recorder and router (``health/shore-*``):
they do not stand for the boat's. With the boat's estimator and controller and the shore's recorder,
the alarm shows; with only the shore's own processes (the boat out of reach) it does not, since
nothing of the vessel is seen running.
"""

from __future__ import annotations

import re
import signal
import time

import pytest
from seaway.runtime.bus import Bus

from tests.conftest import wait_for
from tests.system.groundstation import axe_check
from tests.system.groundstation.helpers import http, start_groundstation

pytestmark = pytest.mark.system
VESSEL = "vessel1"
OTHER = "vessel2"
ALARM = "#recording-status"
FEW_S = 8.0  # the page polls the fleet every 2 s; a withdrawn token reaches the station at once


# True if neither the element nor any of its ancestors is faded.
NOT_FADED = """el => {
    for (let e = el; e; e = e.parentElement) {
        if (Number(getComputedStyle(e).opacity) < 1) return false;
    }
    return true;
}"""
# The fleet table's rows that say the vessel is not recording, by vessel name.
MARKED_ROWS = """() => [...document.querySelectorAll('#fleet-table tbody tr')]
    .filter((tr) => /not\\s+recording/i.test(tr.innerText)).map((tr) => tr.dataset.vessel)"""


def recorder_bus(vessel: str = VESSEL) -> Bus:
    """The recorder's own session with its health token (closing it withdraws the token)."""
    bus = Bus.open(vessel)
    bus.declare_alive("recorder")
    return bus


def services(base: str, vessel: str = VESSEL) -> list[str]:
    status, view = http("GET", base + f"api/vessels/{vessel}")
    return view["services"] if status == 200 else []


def test_a_vessel_without_a_live_recorder_shows_not_recording(procs, zenoh_env, browser,
                                                              tmp_path) -> None:
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    gs, base, _token = start_groundstation(procs, zenoh_env)
    recorder = recorder_bus()
    try:
        with Bus.open(VESSEL) as bus:
            bus.declare_alive("estimator")
            bus.declare_alive("controller")
            wait_for(lambda: {"estimator", "controller", "recorder"} <= set(services(base)), 30,
                     what="the vessel's three services seen by the ground station")
            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(base)
            alarm = page.locator(ALARM)
            # Recorded: the page lists the recorder among the live services, and shows no alarm.
            page.wait_for_function("() => document.getElementById('v-services').textContent"
                                   ".includes('recorder')", timeout=30_000)
            page.wait_for_timeout(1000)  # a render or two more: an alarm would have shown by now
            assert alarm.is_hidden(), alarm.text_content()

            # The recorder fails for good: its token goes, the estimator and controller go on.
            recorder.close()
            gone = time.monotonic()
            alarm.wait_for(state="visible", timeout=FEW_S * 1000)
            print(f"\nthe alarm showed {time.monotonic() - gone:.1f} s after the recorder's token went")
            assert re.search(r"not\s+recording", alarm.inner_text(), re.IGNORECASE), alarm.inner_text()
            # Said to a screen reader: the alarm is (in) a live region.
            assert alarm.evaluate("el => Boolean(el.closest('[role=status], [role=alert], [aria-live]'))")
            # At a glance: in the window as the page opens, not faded.
            box = alarm.bounding_box()
            assert box and box["y"] >= 0 and box["y"] + box["height"] <= 1000, box
            assert alarm.evaluate(NOT_FADED)
            assert {"estimator", "controller"} <= set(services(base))
            page.screenshot(path=str(tmp_path / "not-recording.png"))
            found = axe_check.violations(page, axe_script)
            print("axe-core, not recording:", [(v["id"], v["impact"], len(v["nodes"])) for v in found])
            assert not axe_check.serious(found), axe_check.serious(found)

            # A recorder is back: the alarm goes.
            recorder = recorder_bus()
            back = time.monotonic()
            alarm.wait_for(state="hidden", timeout=FEW_S * 1000)
            print(f"the alarm went {time.monotonic() - back:.1f} s after the recorder's token came back")
            assert "recorder" in page.locator("#v-services").inner_text()
            assert not errors, errors
    finally:
        recorder.close()
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)


def test_the_fleet_table_marks_each_unrecorded_vessel(procs, zenoh_env, browser, tmp_path) -> None:
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    gs, base, _token = start_groundstation(procs, zenoh_env)
    recorders = [recorder_bus(VESSEL)]  # only VESSEL is recorded; OTHER runs without a recorder
    try:
        with Bus.open(VESSEL) as bus:
            for v in (VESSEL, OTHER):
                bus.declare_alive("estimator", vessel=v)
                bus.declare_alive("controller", vessel=v)
            wait_for(lambda: {"estimator", "controller", "recorder"} <= set(services(base, VESSEL))
                     and {"estimator", "controller"} <= set(services(base, OTHER)), 30,
                     what="both vessels' services seen by the ground station")
            assert "recorder" not in services(base, OTHER)
            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(base)
            page.wait_for_function("document.querySelectorAll('#fleet-table tbody tr').length === 2",
                                   timeout=30_000)
            # Exactly the unrecorded vessel's row is marked, whichever vessel is picked.
            page.wait_for_function(f"({MARKED_ROWS})().join() === '{OTHER}'", timeout=FEW_S * 1000)
            page.wait_for_timeout(1000)  # a render or two more: a wrong mark would have shown by now
            assert page.evaluate(MARKED_ROWS) == [OTHER]
            mark = page.locator(f"#fleet-table tr[data-vessel={OTHER}]").get_by_text(
                re.compile(r"not\s+recording", re.IGNORECASE))
            assert mark.count() == 1 and mark.is_visible()
            assert mark.evaluate(NOT_FADED)
            box = mark.bounding_box()
            assert box and box["x"] >= 0 and box["x"] + box["width"] <= 1500, box
            assert box["y"] >= 0 and box["y"] + box["height"] <= 1000, box
            page.screenshot(path=str(tmp_path / "fleet-not-recording.png"))
            found = axe_check.violations(page, axe_script)
            print("\naxe-core, one of two not recording:",
                  [(v["id"], v["impact"], len(v["nodes"])) for v in found])
            assert not axe_check.serious(found), axe_check.serious(found)

            # OTHER's recorder declares its token: no row is marked.
            recorders.append(recorder_bus(OTHER))
            back = time.monotonic()
            page.wait_for_function(f"({MARKED_ROWS})().length === 0", timeout=FEW_S * 1000)
            print(f"the mark went {time.monotonic() - back:.1f} s after the recorder's token came")
            assert len(page.locator("#fleet-table tbody tr").all()) == 2
            assert not errors, errors
    finally:
        for r in recorders:
            r.close()
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)


def test_a_shores_own_recorder_does_not_stand_for_the_boats(procs, zenoh_env, browser) -> None:
    gs, base, _token = start_groundstation(procs, zenoh_env)
    shore = Bus.open(VESSEL)
    shore.side = "shore"  # as a shore process's bus is, from its credentials' rules
    shore.declare_alive("recorder")
    shore.declare_alive("router")
    try:
        with Bus.open(VESSEL) as boat:
            boat.declare_alive("estimator")
            boat.declare_alive("controller")
            wait_for(lambda: {"estimator", "controller", "shore-recorder", "shore-router"}
                     <= set(services(base)), 30, what="the boat's and the shore's tokens")
            page = browser.new_page(viewport={"width": 1500, "height": 1000})
            errors: list[str] = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(base)
            alarm = page.locator(ALARM)
            alarm.wait_for(state="visible", timeout=FEW_S * 1000)
            assert re.search(r"not\s+recording", alarm.inner_text(), re.IGNORECASE)
            assert page.evaluate(MARKED_ROWS) == [VESSEL]
        # The boat out of reach: only the shore's own tokens are left, and no alarm.
        wait_for(lambda: not {"estimator", "controller"} & set(services(base)), 15,
                 what="the boat's tokens gone")
        alarm.wait_for(state="hidden", timeout=FEW_S * 1000)
        assert page.evaluate(MARKED_ROWS) == []
        assert not errors, errors
    finally:
        shore.close()
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
