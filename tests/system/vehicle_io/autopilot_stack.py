"""vehicle_io, the estimator and the controller against an autopilot's own firmware (SITL), for the
system tests of what Seaway believes about that autopilot: its health, its failsafes, its battery.

The test starts the firmware itself (``test_ardupilot_sitl.Sitl``, ``px4_sitl.Px4Sitl``), then
``start_stack`` with the firmware's link; ``Watch`` keeps every message the tests judge with the
monotonic time it arrived.
"""

from __future__ import annotations

import subprocess
import threading
import time
from pathlib import Path

from seaway.contract import keys
from seaway.contract.messages import (
    ArmRequest,
    MissionCommand,
    MissionRequest,
    ModeRequest,
    Reply,
    Waypoint,
)
from seaway.runtime.bus import Bus

from tests.conftest import BIN, Procs, solver_built, wait_for

REQUEST_TIMEOUT_S = 8.0  # an arm reply waits up to 1.5 s for PX4's arming-check report
CONTROLLER = "cc-empc"


def start_stack(procs: Procs, env: dict[str, str], tmp: Path, url: str, autopilot: str,
                vessel_file: str, origin: str) -> dict[str, subprocess.Popen]:
    """vehicle_io on ``url``, the estimator and the controller, modelling ``vessel_file``, the
    local NED origin at ``origin`` ('LAT,LON[,ALT]': the firmware's home). No scenario: a controller
    given one by flag starts its mission at once."""
    solver_built(CONTROLLER, vessel_file)
    run = ["--vessel-file", vessel_file, "--origin", origin]
    cfg = tmp / "vio.toml"
    cfg.write_text(f'mavlink = "{url}"\nautopilot = "{autopilot}"\n')
    return {
        "vio": procs.start([str(BIN / "seaway-vehicle-io"), "--config", str(cfg), *run], env, "vio"),
        "estimator": procs.start([str(BIN / "seaway-estimator"), *run], env, "estimator"),
        "controller": procs.start([str(BIN / "seaway-controller"), *run], env, "controller"),
    }


class Watch:
    """Every VehicleStatus, MissionStatus, EnergyBudget and ThrustCommand, with arrival times."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.lock = threading.Lock()
        self.seen: dict[str, list[tuple[float, object]]] = {}
        for key in (keys.VEHICLE_STATUS, keys.MISSION_STATUS, keys.MISSION_ENERGY, keys.THRUST,
                    keys.NAV_STATE, keys.VEHICLE_BATTERY):
            self.seen[key.suffix] = []
            bus.subscribe(key, callback=self._keep(key.suffix))

    def _keep(self, suffix: str):
        def on(_key: str, msg: object) -> None:
            with self.lock:
                self.seen[suffix].append((time.monotonic(), msg))
        return on

    def of(self, key) -> list[tuple[float, object]]:
        with self.lock:
            return list(self.seen[key.suffix])

    def latest(self, key):
        got = self.of(key)
        return got[-1][1] if got else None

    def first(self, key, pred, timeout_s: float, what: str) -> tuple[float, object]:
        return wait_for(lambda: next(((t, m) for t, m in self.of(key) if pred(m)), None),
                        timeout_s, interval_s=0.1, what=what)

    def mission_in(self, mission_id: str, state: str, timeout_s: float) -> tuple[float, object]:
        """The first MissionStatus of ``mission_id`` (or the return home its energy budget put
        in its place) in ``state``."""
        return self.first(keys.MISSION_STATUS, lambda m: m.mission_id.startswith(mission_id)
                          and m.state == state, timeout_s, f"mission {mission_id!r} {state}")

    def request(self, key, msg) -> Reply:
        return self.bus.request(key, msg, timeout_s=REQUEST_TIMEOUT_S)

    def set_mode(self, mode: str) -> Reply:
        return self.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(), mode=mode))

    def arm_until_accepted(self, timeout_s: float) -> float:
        """Ask to arm until the autopilot agrees (its EKF converging); the monotonic time it did."""
        t0 = time.monotonic()
        while not (reply := self.request(keys.VEHICLE_ARM, ArmRequest.make(
                stamp_ns=time.time_ns(), arm=True))).accepted:
            assert time.monotonic() - t0 < timeout_s, f"never armed; last: {reply.reason}"
            time.sleep(1.0)
        return time.monotonic()

    def send_mission(self, mission_id: str, east_m: float, task_power_w: float,
                     on_low_energy: str = "return", timeout_s: float = 120.0,
                     force: bool = False) -> Reply:
        """A two-waypoint mission east of the origin, sent until the controller answers; ``force``
        flies it although the mission check refuses it on energy."""
        req = MissionRequest.make(
            stamp_ns=time.time_ns(), mission_id=mission_id, coa_radius_m=2.0,
            task_power_w=task_power_w,
            controller=CONTROLLER, join_first_leg=True, on_low_energy=on_low_energy, force=force,
            waypoints=[Waypoint(x_m=0.0, y_m=0.0), Waypoint(x_m=0.0, y_m=east_m)])

        def answered() -> Reply | None:
            reply = self.bus.request(keys.MISSION_SET, req.model_copy(
                update={"stamp_ns": time.time_ns()}), timeout_s=5.0)
            return None if reply.reason.startswith("no reply from") else reply

        return wait_for(answered, timeout_s, interval_s=1.0, what="the controller's answer")

    def command(self, command: str) -> Reply:
        return self.request(keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=time.time_ns(),
                                                                  command=command))
