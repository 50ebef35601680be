"""The telemetry rates after start-up: an autopilot reboot (fast enough that the link never drops)
or a rate drop makes vehicle_io ask for the rates again, and a shortfall it reported is cleared
when the rates recover. Pure logic (``rates.RateWatch``) and the core driven with real packed
MAVLink messages and time passed in."""

from __future__ import annotations

from typing import Any

from seaway.contract.units import NS_PER_S
from seaway_vehicle_io import rates
from seaway_vehicle_io.config import SOURCE_SYSTEM, VehicleIoConfig
from seaway_vehicle_io.core import Now, SendCommandLong, VehicleIoCore
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.thrust import ThrusterLimits

S = NS_PER_S
MS = 1_000_000
WALL0 = 1_800_000_000 * S
LIM = ThrusterLimits(75.0, 75.0, 0.0)


def wire(msg: Any) -> Any:
    tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(tx)))


def at(t_ns: int) -> Now:
    return Now(WALL0 + t_ns, t_ns)


HEARTBEAT = wire(mavlink.MAVLink_heartbeat_message(11, 3, 1 | 128, 0, 4, 3))  # ArduPilot Rover


def asked(outs: list) -> list[SendCommandLong]:
    return [
        o for o in outs if isinstance(o, SendCommandLong) and o.command == rates.MAV_CMD_SET_MESSAGE_INTERVAL
    ]


class Autopilot:
    """Streams ATTITUDE at a settable rate, HEARTBEAT and SYSTEM_TIME at 1 Hz; the core ticks
    every 100 ms. ``reboot`` restarts its clock without a gap in the heartbeat."""

    def __init__(self, core: VehicleIoCore) -> None:
        self.core = core
        self.boot_at_ns = -5 * S  # booted 5 s before vehicle_io started
        self.t_ns = 0
        self.sent: list[SendCommandLong] = []

    def boot_ms(self, t_ns: int) -> int:
        return (t_ns - self.boot_at_ns) // MS

    def run(self, seconds: float, attitude_hz: float) -> None:
        end = self.t_ns + round(seconds * S)
        step_att = round(S / attitude_hz)
        events = [(t, "att") for t in range(self.t_ns, end, step_att)]
        events += [(t, "hb") for t in range(self.t_ns, end, S)]
        events += [(t, "tick") for t in range(self.t_ns, end, 100 * MS)]
        for t, kind in sorted(events):
            if kind == "att":
                out = self.core.on_mavlink(
                    wire(mavlink.MAVLink_attitude_message(self.boot_ms(t), 0.0, 0.0, 0.5, 0.0, 0.0, 0.1)),
                    at(t),
                )
            elif kind == "hb":
                out = self.core.on_mavlink(HEARTBEAT, at(t))
                out += self.core.on_mavlink(
                    wire(mavlink.MAVLink_system_time_message((WALL0 + t) // 1000, self.boot_ms(t))), at(t)
                )
            else:
                out = self.core.tick(at(t))
            new = asked(out)
            for _ in new:  # the autopilot takes each request
                self.core.on_mavlink(
                    wire(
                        mavlink.MAVLink_command_ack_message(
                            rates.MAV_CMD_SET_MESSAGE_INTERVAL, 0, 0, 0, SOURCE_SYSTEM, 191
                        )
                    ),
                    at(t),
                )
            self.sent += new
        self.t_ns = end

    def reboot(self) -> None:
        self.boot_at_ns = self.t_ns

    def short(self) -> dict[str, float] | None:
        return self.core.status(at(self.t_ns)).telemetry_rates_short


def connected() -> Autopilot:
    core = VehicleIoCore(
        VehicleIoConfig(autopilot="auto", message_rates_hz={"ATTITUDE": 10.0}, check_failsafe_params=False),
        LIM,
        at(0),
    )
    ap = Autopilot(core)
    ap.run(5.0, attitude_hz=10.0)
    assert len(ap.sent) == 1 and ap.short() == {}  # asked once, at connection; all at the rate
    return ap


# -- pure logic ------------------------------------------------------------------------------------


def test_a_drop_is_confirmed_over_seconds_and_a_recovery_clears_it():
    plan = rates.plan({"ATTITUDE": 10.0, "SYS_STATUS": 1.0})
    watch = rates.RateWatch(plan)
    watch.checked({})
    assert watch.window({"ATTITUDE": 20, "SYS_STATUS": 1}, 0, 2 * S) is None  # one short of 2
    assert watch.window({"ATTITUDE": 2, "SYS_STATUS": 2}, 2 * S, 4 * S) is None  # not yet 4 s
    assert watch.short == {}
    assert watch.window({"ATTITUDE": 2, "SYS_STATUS": 2}, 4 * S, 6 * S) == "drop"
    assert watch.short == {"ATTITUDE": 1.0}
    assert watch.window({"ATTITUDE": 3, "SYS_STATUS": 2}, 6 * S, 8 * S) is None  # still short
    assert watch.window({"ATTITUDE": 19, "SYS_STATUS": 2}, 8 * S, 10 * S) == "recovered"
    assert watch.short == {}


def test_one_short_window_between_good_ones_is_no_drop():
    watch = rates.RateWatch(rates.plan({"ATTITUDE": 10.0}))
    watch.checked({})
    for k in range(10):
        counts = {"ATTITUDE": 3 if k % 2 else 20}
        assert watch.window(counts, k * 2 * S, (k + 1) * 2 * S) is None
    assert watch.short == {}


def test_a_boot_time_shortfall_is_standing_until_the_rates_recover():
    watch = rates.RateWatch(rates.plan({"ATTITUDE": 10.0}))
    assert watch.short is None  # not decided before the check ends
    watch.checked({"ATTITUDE": 1.0})
    assert watch.window({"ATTITUDE": 20}, 0, 2 * S) == "recovered" and watch.short == {}


# -- the core -------------------------------------------------------------------------------------


def test_a_fast_reboot_without_a_heartbeat_gap_asks_for_the_rates_again():
    ap = connected()
    ap.reboot()
    ap.run(2.0, attitude_hz=1.0)  # its defaults after the reboot; the heartbeat never paused
    assert len(ap.sent) == 2  # asked again once SYSTEM_TIME went back for a second
    ap.run(6.0, attitude_hz=10.0)  # and it took the request
    assert len(ap.sent) == 2 and ap.short() == {}


def test_a_rate_drop_is_asked_again_reported_and_cleared_when_it_recovers():
    ap = connected()
    ap.run(3.0, attitude_hz=1.0)  # dropped, no reboot seen
    assert len(ap.sent) == 1 and ap.short() == {}  # not yet a drop: could be a slow window
    ap.run(4.0, attitude_hz=1.0)
    assert len(ap.sent) == 2  # a drop standing for seconds: asked again
    ap.run(4.0, attitude_hz=1.0)  # the request did not cure it
    short = ap.short()
    assert short is not None and set(short) == {"ATTITUDE"} and 0.5 <= short["ATTITUDE"] <= 1.5
    ap.run(4.0, attitude_hz=10.0)
    assert ap.short() == {}  # recovered: the warning is cleared
    n = len(ap.sent)
    ap.run(20.0, attitude_hz=1.0)  # a standing drop is asked again, but not at every window
    assert n + 1 <= len(ap.sent) <= n + 1 + 20 / rates.REREQUEST_EVERY_S
