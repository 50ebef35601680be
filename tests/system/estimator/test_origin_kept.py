"""A boat's estimator (no origin configured) takes its first fix as the NED origin. Killed and
restarted in the same run, it must start from that origin, not from wherever the vessel is by then:
the mission, the area and the home are held in local metres of the first one."""

from __future__ import annotations

import math
import signal
import threading
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import Attitude, GnssFix, NavOrigin
from seaway.runtime.bus import Bus
from seaway.vessel.frames import GeoOrigin

from tests.conftest import BIN, wait_for
from tests.system.estimator.test_estimator_process import _ready

pytestmark = pytest.mark.system
FIRST = GeoOrigin.from_degrees(47.0, 8.0, 0.0)  # where the vessel is when the estimator starts


def _feed(bus: Bus, north_m: float, stop: threading.Event) -> None:
    """A vessel at rest ``north_m`` of FIRST: a fix and an attitude at 20 Hz, stamped now."""
    g, a = bus.publisher(keys.GNSS), bus.publisher(keys.ATTITUDE)
    lat, lon, _ = FIRST.to_geodetic(north_m, 0.0, 0.0)
    while not stop.wait(0.05):  # the sensors' pace, not a timing
        now = time.time_ns()
        g.put(GnssFix(stamp_ns=now, lat_rad=lat, lon_rad=lon, alt_m=0.0, fix_type=3,
                      vel_n_mps=0.0, vel_e_mps=0.0, horizontal_std_m=0.3))
        a.put(Attitude(stamp_ns=now, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0, roll_rate_radps=0.0,
                       pitch_rate_radps=0.0, yaw_rate_radps=0.0))


def _origin_and_state(bus: Bus, north_m: float) -> tuple[NavOrigin, float]:
    """The origin the estimator publishes and its north estimate [m], with the vessel ``north_m``
    of FIRST."""
    origins = bus.subscribe(keys.NAV_ORIGIN, mode="fifo")
    states = bus.subscribe(keys.NAV_STATE, mode="fifo")
    stop = threading.Event()
    feeder = threading.Thread(target=_feed, args=(bus, north_m, stop), daemon=True)
    feeder.start()
    try:
        origin = wait_for(lambda: origins.get(0.1), 20, what="nav/origin")
        state = wait_for(lambda: states.get(0.1), 20, what="nav/state")
    finally:
        stop.set()
        feeder.join(5)
    origins.undeclare()
    states.undeclare()
    return origin, state.x_m


def test_a_restarted_estimator_keeps_the_origin_it_took_from_its_first_fix(procs, zenoh_env, tmp_path
                                                                            ) -> None:
    kept = tmp_path / "estimator-state.json"
    cmd = [str(BIN / "seaway-estimator"), "--state-file", str(kept)]
    est = procs.start(cmd, zenoh_env, "est-first")
    with Bus.open("vessel1") as bus:
        wait_for(lambda: _ready(bus), 30, what="the estimator")
        first, x_m = _origin_and_state(bus, 0.0)
        assert abs(first.lat_rad - FIRST.lat_rad) < 1e-9 and abs(x_m) < 1.0
        wait_for(kept.exists, 10, what="the kept origin")
        procs.stop(est, signal.SIGKILL)  # a crash: nothing written at the end
        # The vessel moved on meanwhile: 200 m north when the restarted estimator hears it.
        est = procs.start(cmd, zenoh_env, "est-restarted")
        wait_for(lambda: _ready(bus), 30, what="the restarted estimator")
        again, x_m = _origin_and_state(bus, 200.0)
    assert procs.stop(est) < 5.0
    assert (again.lat_rad, again.lon_rad, again.alt_m) == (first.lat_rad, first.lon_rad, first.alt_m)
    assert math.isclose(x_m, 200.0, abs_tol=2.0), x_m  # in the first frame, not at a new 0
    assert "origin kept" in procs.log(est).lower()
