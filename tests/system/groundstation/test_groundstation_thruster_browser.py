"""A thruster short of its command on the page, in a real browser (Debian's chromium driven by
Playwright): the real ``seaway-groundstation`` process and a vessel the test plays on a real Zenoh
session, whose estimator says the starboard thruster gives 34 % less than commanded
(``StateEstimate.thrust_short_side``, ``seaway_estimator.asymmetry``), then a motion fault, then
neither. The progress panel's motion row says which, as a warning, a fault, or nothing; axe-core
finds no serious or critical violation with the warning shown.
"""

from __future__ import annotations

import signal

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionStatus, StateEstimate
from seaway.runtime.bus import Bus

from tests.conftest import wait_for
from tests.system.groundstation import axe_check
from tests.system.groundstation.helpers import playing, start_groundstation, vessel_page

pytestmark = pytest.mark.system
VESSEL = "vessel1"


def test_a_thruster_short_of_its_command_is_shown_as_a_warning(procs, zenoh_env, browser) -> None:
    try:
        axe_script = axe_check.install()
    except axe_check.AxeUnavailableError as err:
        pytest.skip(str(err))
    gs, base, _token = start_groundstation(procs, zenoh_env)
    said: dict[str, object] = {"thrust_short_side": "starboard", "thrust_short_frac": 0.34}
    with Bus.open(VESSEL) as bus:
        bus.publisher(keys.MISSION_STATUS).put(MissionStatus.make(stamp_ns=1, state="active",
                                                                  active_leg=1, waypoint_count=4))
        # The state at 5 Hz, with what the test says now.
        with playing(bus.publisher(keys.NAV_STATE).put, lambda k: StateEstimate.make(
                stamp_ns=k * 200_000_000, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.0, y_m=0.0,
                psi_rad=0.0, **said)):
            page, errors = vessel_page(browser, base, VESSEL)
            motion = page.locator("#p-motion")

            def shows(*words: str) -> bool:
                text = motion.text_content() or ""
                return all(w in text for w in words)

            wait_for(lambda: shows("STARBOARD", "34 %"), 30, what="the starboard thruster shown short")
            assert motion.get_attribute("class") == "warn"
            found = axe_check.violations(page, axe_script)
            assert not axe_check.serious(found), axe_check.serious(found)
            said.update(motion_fault="not_moving", motion_fault_detail="held")  # says more
            wait_for(lambda: shows("FAULT not_moving"), 10, what="the motion fault instead")
            assert "STARBOARD" not in (motion.text_content() or "")
            assert motion.get_attribute("class") == "bad"
            said.clear()
            wait_for(lambda: shows("no fault"), 10, what="neither once the estimator says neither")
            assert motion.get_attribute("class") == ""
            assert not errors, errors
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
