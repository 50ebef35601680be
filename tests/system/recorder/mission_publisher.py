"""A stand-in for sim + controller in recorder tests: a known mission run published on the bus.

``generate()`` builds a deterministic run on the paper's path (P0 (0,0), P1 (8,0), P2 (5.13,8.57), r_COA
1 m, T^w 0.49 W, alpha 0.4364 W/N^2): 1 s idle at P0 (holding thrust, mission idle), then a kinematic
boat steering toward the active waypoint with a sideways drift (so the cross-track error is not zero),
thrusts that vary with time and with the turn, leg switching on entering each circle of acceptance,
and 1.5 s after completion. Every 0.1 s (sim time) it emits sim/truth, ctrl/thrust (stamped with the
state it follows), ctrl/solve (known solve times, a few failures with fallbacks), mission/status
(with the live energy used, computed as a controller would), nav/state, and sensors/gnss at 5 Hz;
nav/origin once at the start. With ``with_energy`` (``--energy``) also mission/energy each active step
and vehicle/battery at 1 Hz: a budget whose prediction of the energy to finish is off by a known
fraction (``prediction_bias``) of what finishing actually takes, a battery that takes the 'warn'
decision part way (``BATTERY_START_J``), and its point of no return (``energy_budget``).

Run as a process: publishes every message of ``generate()`` in order (``--pace`` seconds apart; 0 for
as fast as the bus takes them), after ``--malformed N`` malformed samples; prints ``READY`` once the
recorder is subscribed, then a JSON line with what it sent and its live metrics. ``--steady HZ``
instead publishes ThrustCommand stamped with the wall time of sending until killed (crash tests).
"""

from __future__ import annotations

import argparse
import json
import math
import re
import signal
import time

from seaway.contract import keys
from seaway.contract.messages import (
    BatteryState,
    EnergyBudget,
    GnssFix,
    MissionStatus,
    NavOrigin,
    SimTruth,
    SolveRecord,
    StateEstimate,
    ThrustCommand,
)
from seaway.vessel.frames import GeoOrigin

WAYPOINTS = [(0.0, 0.0), (8.0, 0.0), (5.13, 8.57)]
COA_M = 1.0
TASK_POWER_W = 0.49
ALPHA = 0.4364
DT_S = 0.1
DT_NS = 100_000_000
IDLE_STEPS = 10
TAIL_STEPS = 15
ORIGIN = GeoOrigin(math.radians(47.0), math.radians(8.0), 0.0)
FAILED_SOLVES = {37, 38, 90}  # step indices after the start whose solve fails
BATTERY_START_J = 160.0
"""The battery's remaining energy when the mission starts [J] (--energy)."""
RESERVE_J = 20.0
HOME_J_PER_M = 3.0
"""The budget's energy to get home: this much per metre from P0 [J/m]."""


def prediction_bias(frac: float) -> float:
    """(predicted - actual) / actual of the energy to finish, at ``frac`` of the mission's time."""
    return 0.10 - 0.15 * frac


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def generate(vessel: str = "vessel1", with_energy: bool = False) -> tuple[list[tuple[str, bytes]], dict]:
    """The run's messages ``(key, bytes)`` in publication order, and the live metrics (with
    ``with_energy``, the budget's too: ``live["energy_budget"]``)."""
    out: list[tuple[str, bytes] | None] = []
    # (slot in out, stamp, energy used since the start, x, y) of each active step: the budget's
    # figures need the whole run, so they are filled in once it is known.
    slots: list[tuple[int, int, float, float, float]] = []

    def put(spec, msg) -> None:
        out.append((spec.key(vessel), msg.encode()))

    put(keys.NAV_ORIGIN, NavOrigin.make(stamp_ns=0, lat_rad=ORIGIN.lat_rad, lon_rad=ORIGIN.lon_rad,
                                        alt_m=ORIGIN.alt_m))
    x = y = psi = 0.0
    energy = 0.0
    leg = 1
    state = "idle"
    complete_step = None
    live_energy = 0.0
    energy_at_start = 0.0
    k = 0
    mission_start_ns = 0
    complete_t_ns = 0
    while True:
        t_ns = k * DT_NS
        t = t_ns / 1e9
        if k == IDLE_STEPS:
            state = "active"
            mission_start_ns = t_ns
            energy_at_start = energy
        # Thrusts for the step that starts now (held until the next sample).
        if state == "idle":
            t1 = t2 = 0.3
            speed = 0.0
            rate = 0.0
        elif state == "active":
            wx, wy = WAYPOINTS[leg]
            err = _wrap(math.atan2(wy - y, wx - x) - psi)
            rate = max(-0.5, min(0.5, 1.5 * err))
            base = 2.0 + 0.4 * math.sin(0.7 * t)
            t1, t2 = base + 0.8 * rate, base - 0.8 * rate
            speed = 0.45 + 0.05 * math.sin(0.3 * t)
        else:  # complete: hold position with a little thrust
            t1 = t2 = 0.2
            speed = 0.0
            rate = 0.0
        u = speed
        truth = SimTruth.make(stamp_ns=t_ns, u_mps=u, v_mps=0.0, r_radps=rate, x_m=x, y_m=y,
                              psi_rad=_wrap(psi), thrust_port_n=t1, thrust_starboard_n=t2, energy_j=energy)
        put(keys.SIM_TRUTH, truth)
        put(keys.NAV_STATE, StateEstimate.make(stamp_ns=t_ns, u_mps=u, v_mps=0.0, r_radps=rate,
                                               x_m=x + 0.01, y_m=y - 0.01, psi_rad=_wrap(psi)))
        if k % 2 == 0:
            lat, lon, alt = ORIGIN.to_geodetic(x, y, 0.0)
            put(keys.GNSS, GnssFix.make(stamp_ns=t_ns, lat_rad=lat, lon_rad=lon, alt_m=alt, fix_type=3,
                                        horizontal_std_m=0.5))
        put(keys.THRUST, ThrustCommand.make(stamp_ns=t_ns, thrust_port_n=t1, thrust_starboard_n=t2,
                                            source="test", seq=k))
        if state == "active":
            step = k - IDLE_STEPS
            ok = step not in FAILED_SOLVES
            put(keys.SOLVE, SolveRecord.make(
                stamp_ns=t_ns, controller="cc-empc", status="Solve_Succeeded" if ok else "Maximum_Iterations",
                success=ok, iterations=10 + step % 7, solve_time_s=0.004 + 0.001 * (step % 10),
                fallback_level=0 if ok else 2, fallback_count=sum(1 for f in FAILED_SOLVES if f <= step),
                leg_energy_to_go_j=max(0.0, 100.0 - 0.5 * step)))
        # The live metric a controller would report: energy since the mission started, incl. T^w,
        # frozen when the mission completes.
        if state == "active":
            live_energy = (energy - energy_at_start) + TASK_POWER_W * (t_ns - mission_start_ns) / 1e9
        put(keys.MISSION_STATUS, MissionStatus.make(
            stamp_ns=t_ns, state=state, mission_id="test", active_leg=min(leg, 2), waypoint_count=3,
            energy_used_j=None if state == "idle" else live_energy))
        if with_energy and state != "idle":
            if state == "active":
                slots.append((len(out), t_ns, live_energy, x, y))
                out.append(None)
            if k % 10 == 0:
                put(keys.VEHICLE_BATTERY, BatteryState.make(
                    stamp_ns=t_ns, source="sim", remaining_j=BATTERY_START_J - live_energy,
                    reserve_j=RESERVE_J))
        if complete_step is not None and k >= complete_step + TAIL_STEPS:
            break
        # Advance to the next sample.
        energy += ALPHA * (t1 * t1 + t2 * t2) * DT_S
        psi += rate * DT_S
        x += (u * math.cos(psi)) * DT_S
        y += (u * math.sin(psi) + (0.06 if state == "active" else 0.0)) * DT_S
        k += 1
        if state == "active":
            while leg < len(WAYPOINTS) and math.hypot(x - WAYPOINTS[leg][0], y - WAYPOINTS[leg][1]) <= COA_M:
                leg += 1
            if leg >= len(WAYPOINTS):
                state = "complete"
                complete_step = k
                complete_t_ns = k * DT_NS
                live_energy = ((energy - energy_at_start)
                               + TASK_POWER_W * (complete_t_ns - mission_start_ns) / 1e9)
        if k > 5000:
            raise RuntimeError("the test boat never finished the mission")
    live = {"energy_j": live_energy, "travel_time_s": (complete_t_ns - mission_start_ns) / 1e9,
            "mission_start_ns": mission_start_ns, "complete_ns": complete_t_ns}
    if with_energy:
        live["energy_budget"] = _fill_budgets(out, slots, vessel, live_energy, mission_start_ns,
                                              complete_t_ns)
    assert all(m is not None for m in out)
    return out, live  # type: ignore[return-value]


def _fill_budgets(out: list, slots: list[tuple[int, int, float, float, float]], vessel: str,
                  total_j: float, start_ns: int, end_ns: int) -> dict:
    """Put each active step's EnergyBudget into its slot; what the budget said, for the test."""
    def margin(used: float, x: float, y: float) -> float:
        return BATTERY_START_J - used - HOME_J_PER_M * math.hypot(x, y) - RESERVE_J

    decided = next((i for i, (_, _, e, x, y) in enumerate(slots) if margin(e, x, y) <= 0), None)
    if decided is None:
        raise RuntimeError("the test battery never takes its decision: lower BATTERY_START_J")
    decided_ns = slots[decided][1]
    reason = "energy to get home + reserve reached the battery's energy left (test)"
    for i, (at, t_ns, used, x, y) in enumerate(slots):
        actual = total_j - used
        predicted = actual * (1 + prediction_bias((t_ns - start_ns) / (end_ns - start_ns)))
        home = HOME_J_PER_M * math.hypot(x, y)
        pnr: dict = {}
        if i < decided:  # where the margin reaches 0: the decision's position, along the track
            track = sum(math.dist(slots[j][3:], slots[j + 1][3:]) for j in range(i, decided))
            pnr = dict(no_return_x_m=slots[decided][3], no_return_y_m=slots[decided][4],
                       no_return_along_m=track)
        out[at] = (keys.MISSION_ENERGY.key(vessel), EnergyBudget.make(
            stamp_ns=t_ns, mission_id="test", active_leg=1, energy_used_j=used,
            leg_energy_to_go_j=None, energy_to_go_j=predicted, energy_to_go_low_j=0.9 * predicted,
            energy_to_go_high_j=1.1 * predicted, energy_to_home_j=home,
            energy_to_home_low_j=0.9 * home, energy_to_home_high_j=1.1 * home,
            home_x_m=WAYPOINTS[0][0], home_y_m=WAYPOINTS[0][1],
            battery_remaining_j=BATTERY_START_J - used, battery_stamp_ns=t_ns, reserve_j=RESERVE_J,
            margin_j=margin(used, x, y), finish_margin_j=BATTERY_START_J - used - predicted - RESERVE_J,
            policy="warn", decision="warn" if i >= decided else "none",
            decided_ns=decided_ns if i >= decided else None,
            reason=reason if i >= decided else "", **pnr).encode())
    return {"decided_ns": decided_ns, "reason": reason, "first_no_return": slots[decided][3:],
            "last_used_j": slots[-1][2], "last_home_j": HOME_J_PER_M * math.hypot(*slots[-1][3:])}


MALFORMED = [
    ("sim/truth", b'{"stamp_ns": 5, "u_mps": NaN}'),
    ("nav/state", b"not json at all"),
    ("ctrl/thrust", b'{"stamp_ns": -1, "thrust_port_n": 1, "thrust_starboard_n": 2}'),
]


STATUS_INTERVAL_S = 0.2
"""The recorder's --status-interval in these tests: how often it says how many it has written."""
_WRITTEN = re.compile(r"messages ([\d,]+), bytes [\d,]+, malformed ([\d,]+)")


def written(log: str) -> int:
    """Messages the recorder has taken so far (written, malformed ones included), from its latest
    status line (``RecorderStats.line``) in ``log``."""
    found = _WRITTEN.findall(log)
    if not found:
        return 0
    messages, malformed = found[-1]
    return int(messages.replace(",", "")) + int(malformed.replace(",", ""))


def stop_when_written(procs, rec, count: int, timeout_s: float = 30.0) -> None:
    """SIGTERM the recorder once it has taken ``count`` messages. The publisher's last put only
    queues its sample (Zenoh's BLOCK congestion control); on a busy machine samples were still on
    their way when the recorder was stopped 0.3 s later, and the run lacked its end."""
    deadline = time.monotonic() + timeout_s
    while (got := written(procs.log(rec))) < count:  # no tests.conftest: this also runs alone
        assert time.monotonic() < deadline, f"the recorder took {got} of {count} messages"
        time.sleep(0.05)
    procs.stop(rec, signal.SIGTERM, timeout_s=30)


def steady(session, vessel: str, rate_hz: float) -> None:
    """ThrustCommand at ``rate_hz`` until killed; stamp_ns is the wall time of sending, seq counts."""
    import zenoh

    pub = session.declare_publisher(keys.THRUST.key(vessel),
                                    congestion_control=zenoh.CongestionControl.BLOCK)
    _wait_matching([pub])
    print("READY", flush=True)
    n = 0
    t0 = time.monotonic()
    while True:
        n += 1
        pub.put(ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=1.0, thrust_starboard_n=1.0,
                                   source="steady", seq=n).encode())
        delay = t0 + n / rate_hz - time.monotonic()
        if delay > 0:
            time.sleep(delay)


def _wait_matching(pubs) -> None:
    deadline = time.monotonic() + 20
    while not all(p.matching_status.matching for p in pubs):
        if time.monotonic() > deadline:
            raise SystemExit("no recorder subscribed")
        time.sleep(0.05)
    time.sleep(0.3)


def main() -> int:
    import zenoh
    from seaway.runtime.zenoh_bus import open_session

    ap = argparse.ArgumentParser()
    ap.add_argument("--vessel", default="vessel1")
    ap.add_argument("--pace", type=float, default=0.0, help="seconds between samples (0: no wait)")
    ap.add_argument("--malformed", type=int, default=0)
    ap.add_argument("--energy", action="store_true", help="also mission/energy and vehicle/battery")
    ap.add_argument("--steady", type=float, default=0.0,
                    help="instead: ThrustCommand at this rate [Hz] until killed")
    args = ap.parse_args()
    session = open_session()
    if args.steady:
        steady(session, args.vessel, args.steady)
        return 0
    msgs, live = generate(args.vessel, with_energy=args.energy)
    pubs = {}
    for key, _ in msgs:
        if key not in pubs:
            spec = keys.spec_for_key(key)
            enc = zenoh.Encoding.APPLICATION_JSON.with_schema(spec.message.SCHEMA)
            pubs[key] = session.declare_publisher(key, encoding=enc,
                                                  congestion_control=zenoh.CongestionControl.BLOCK)
    _wait_matching(pubs.values())
    print("READY", flush=True)
    for suffix, payload in MALFORMED[: args.malformed]:
        session.put(f"seaway/{args.vessel}/{suffix}", payload)
    for key, data in msgs:
        pubs[key].put(data)
        if args.pace:
            time.sleep(args.pace)
    time.sleep(0.3)
    print(json.dumps({"sent": len(msgs), "malformed": args.malformed, "live": live}), flush=True)
    session.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
