"""Stale figures stay readable, in a real browser (Debian's chromium driven by Playwright): the real
``seaway-groundstation`` process, a vessel the test plays on a real Zenoh session whose vehicle and
mission status fall silent while its state goes on. Those panels are marked stale (their badge),
and axe-core finds no serious or critical violation on the page: a stale value is old, not
unreadable (a crew in sunlight reads it to judge how old).
"""

from __future__ import annotations

import signal

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionStatus, StateEstimate, VehicleStatus
from seaway.runtime.bus import Bus

from tests.system.groundstation import axe_check
from tests.system.groundstation.helpers import playing, start_groundstation, vessel_page

pytestmark = pytest.mark.system
VESSEL = "vessel1"


def test_stale_panels_are_marked_and_still_pass_axe(procs, zenoh_env, browser, tmp_path) -> None:
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    gs, base, _token = start_groundstation(procs, zenoh_env)
    with Bus.open(VESSEL) as bus:
        bus.publisher(keys.MISSION_STATUS).put(MissionStatus.make(stamp_ns=1, state="idle"))
        bus.publisher(keys.VEHICLE_STATUS).put(VehicleStatus.make(
            stamp_ns=1, autopilot="px4", link_ok=True, armed=False, mode="HOLD"))
        # The state at 5 Hz; the two statuses once, then never again.
        with playing(bus.publisher(keys.NAV_STATE).put, lambda k: StateEstimate.make(
                stamp_ns=k * 200_000_000, u_mps=0.0, v_mps=0.0, r_radps=0.0, x_m=0.0, y_m=0.0,
                psi_rad=0.0)):
            page, errors = vessel_page(browser, base, VESSEL)
            for panel in ("vehicle", "mission"):
                page.wait_for_selector(f"[data-stale='{panel}']", state="visible", timeout=30_000)
            for panel in ("vessel-panel", "progress-panel"):  # their figures shown as stale
                page.wait_for_selector(f"#{panel} dl.is-stale", timeout=10_000)
            page.screenshot(path=str(tmp_path / "stale.png"))
            found = axe_check.violations(page, axe_script)
            print("axe-core, stale panels:", [(v["id"], v["impact"], len(v["nodes"])) for v in found])
            assert not axe_check.serious(found), axe_check.serious(found)
            assert not errors, errors
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
