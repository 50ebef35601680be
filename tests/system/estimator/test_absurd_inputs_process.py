"""The real-time estimator process on a real Zenoh session, fed valid messages that say absurd
things (a fix of 1e200 m std, one 5000 km away, 1e5 m/s over ground, a yaw rate of 1e5 rad/s), stale
copies of used ones and a fix stamped ahead of the clock, among good samples: it refuses them with
a logged reason, counts them, and keeps publishing finite estimates; it never drops its state."""

from __future__ import annotations

import math
import re
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import Attitude, GnssFix
from seaway.runtime.bus import Bus
from seaway.vessel.frames import MAX_RANGE_M, GeoOrigin

from tests.conftest import BIN, wait_for
from tests.system.estimator.test_estimator_process import _ready

pytestmark = pytest.mark.system
ORIGIN = GeoOrigin.from_degrees(47.0, 8.0, 0.0)


def _fix(t_ns: int, north_m: float = 0.0, std_m: float = 0.3, vel_n_mps: float = 0.0) -> GnssFix:
    lat, lon, _ = ORIGIN.to_geodetic(north_m, 0.0, 0.0)
    return GnssFix(stamp_ns=t_ns, lat_rad=lat, lon_rad=lon, alt_m=0.0, fix_type=3,
                   vel_n_mps=vel_n_mps, vel_e_mps=0.0, horizontal_std_m=std_m)


def _att(t_ns: int, yaw_rate_radps: float = 0.0) -> Attitude:
    return Attitude(stamp_ns=t_ns, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0, roll_rate_radps=0.0,
                    pitch_rate_radps=0.0, yaw_rate_radps=yaw_rate_radps)


def _stat(log: str, name: str) -> int:
    found = re.findall(rf"estimator final: .*?\b{name} (\d+)", log)
    assert found, f"no {name} in the final stats line"
    return int(found[-1])


def test_realtime_process_refuses_absurd_inputs_and_keeps_its_state(procs, zenoh_env) -> None:
    est = procs.start([str(BIN / "seaway-estimator"), "--origin", "47.0,8.0"], zenoh_env, "est-abs")
    wait_for(lambda: "estimator realtime" in procs.log(est), 20, what="estimator up")
    with Bus.open("vessel1") as bus:
        wait_for(lambda: _ready(bus), 20, what="the reset queryable")
        states = bus.subscribe(keys.NAV_STATE, mode="fifo")
        g, a = bus.publisher(keys.GNSS), bus.publisher(keys.ATTITUDE)
        sent: list[int] = []
        for k in range(60):  # 3 s of a vessel at rest at the origin, sensors at 20 Hz
            now = time.time_ns()
            absurd = 10 <= k < 40
            g.put(_fix(now, std_m=0.3))
            a.put(_att(now, yaw_rate_radps=1e5 if absurd else 0.0))
            if absurd:
                g.put(_fix(now + 1, std_m=1e200))
                g.put(_fix(now + 2, north_m=5e6))
                g.put(_fix(now + 3, vel_n_mps=1e5))
                for old in sent[-3:]:  # stale copies of fixes already used
                    g.put(_fix(old))
            if k == 20:
                g.put(_fix(now + 900_000_000))  # within the stamp gate's second ahead
            sent.append(now)
            time.sleep(0.05)
        wait_for(lambda: states.get(0.1) is not None, 5, what="nav/state after the inputs")
        got = states.drain()
    assert procs.stop(est) < 5.0
    log = procs.log(est)
    assert "Traceback" not in log
    assert "divergence reset" not in log and "time jump" not in log
    for name in ("gnss_refused", "sog_refused", "yaw_rate_refused", "duplicates"):
        assert _stat(log, name) > 0, name
    assert "refused" in log.lower()
    # What was published meanwhile: finite, in the frame's range, at rest.
    assert got
    for m in got:
        assert all(math.isfinite(v) for v in (m.u_mps, m.v_mps, m.r_radps, m.x_m, m.y_m))
        assert abs(m.x_m) < MAX_RANGE_M and math.hypot(m.u_mps, m.v_mps) < 1.0
