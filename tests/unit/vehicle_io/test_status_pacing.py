"""The statuses vehicle_io says at once are paced (``status_pacing``): a locked autopilot flapping
its HEARTBEAT 10,000 times a second made 10,000 VehicleStatus a second. Now at most one per
``MIN_STATUS_GAP_NS`` goes out at once, a change within the gap is said at its end with the latest
state, and a change after a quiet spell is still said at once. Pure: time passed in."""

from __future__ import annotations

import math
import threading
import time

import pytest
from seaway.contract.messages import VehicleStatus
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.node import VehicleIoNode
from seaway_vehicle_io.status_pacing import MIN_STATUS_GAP_NS, StatusPacer

from tests.unit.vehicle_io.test_core import LIM, MS, S, at, connected, heartbeat, published, thrust

GAP = MIN_STATUS_GAP_NS
PX4_MANUAL = 1 << 16
PX4_HOLD = (4 << 16) | (3 << 24)


# -- the pacer alone ------------------------------------------------------------------------------


def test_the_gap_is_50_ms() -> None:
    assert GAP == 50 * MS


def test_the_first_change_and_one_after_the_gap_go_out_at_once() -> None:
    p = StatusPacer()
    assert p.may_say(10 * MS) and p.next_due_ns() is None
    assert p.may_say(10 * MS + GAP) and p.next_due_ns() is None
    assert p.held == 0


def test_a_change_within_the_gap_is_held_to_its_end() -> None:
    p = StatusPacer()
    assert p.may_say(0)
    assert not p.may_say(1 * MS)
    assert not p.may_say(30 * MS)  # still due at the end of the same gap, not pushed back
    assert p.next_due_ns() == GAP and p.held == 2
    assert not p.due(GAP - 1) and p.due(GAP)
    assert p.may_say(GAP)  # said at the gap's end: the next gap starts there
    assert p.next_due_ns() is None
    assert not p.may_say(GAP + 1 * MS) and p.next_due_ns() == 2 * GAP


def test_any_status_said_clears_what_was_held() -> None:
    """A periodic status carries the latest state too: nothing is left to say after it."""
    p = StatusPacer()
    p.may_say(0)
    p.may_say(1 * MS)
    p.said()
    assert p.next_due_ns() is None and not p.due(S)


def test_the_gap_must_be_positive() -> None:
    with pytest.raises(ValueError, match="gap_ns"):
        StatusPacer(0)


# -- the core ---------------------------------------------------------------------------------------


def run_until(core, end_ns: int) -> list[VehicleStatus]:
    """The node's timer: ``tick`` at every time the core says something is due, up to ``end_ns``.
    Returns the VehicleStatus published."""
    statuses: list[VehicleStatus] = []
    while (due := core.next_wake_ns()) <= end_ns:
        statuses += published(core.tick(at(due)), VehicleStatus)
    return statuses


def flap(core, n: int, t0_ns: int, span_ns: int) -> tuple[int, list[VehicleStatus]]:
    """``n`` HEARTBEATs in ``span_ns`` from ``t0_ns``, alternating armed and disarmed (the last one
    disarmed when ``n`` is even), with the timer's ticks in between. Returns the time of the last
    HEARTBEAT and every VehicleStatus published."""
    statuses: list[VehicleStatus] = []
    t = t0_ns
    for i in range(n):
        t = t0_ns + i * span_ns // n
        statuses += run_until(core, t)
        statuses += published(core.on_mavlink(heartbeat(armed=i % 2 == 0), at(t)), VehicleStatus)
        assert core.link.armed == (i % 2 == 0)  # the state follows every HEARTBEAT
    return t, statuses


def test_a_flapping_autopilot_makes_a_bounded_number_of_statuses() -> None:
    core = connected()
    core.tick(at(2 * MS))
    last_ns, statuses = flap(core, 10_000, 100 * MS, S)
    periodic = math.ceil(core.cfg.status_rate_hz) + 1  # in the 1 s and at its ends
    print(f"10,000 flapping HEARTBEATs in 1 s: {len(statuses)} VehicleStatus published")
    assert len(statuses) <= S // GAP + periodic + 2  # was 10,000
    assert len(statuses) >= S // GAP // 2  # and still said, at the pace allowed
    # The burst is over, its last word "disarmed": said by the gap's end.
    assert core.status_pacer.next_due_ns() is not None  # held: the last was said within the gap
    assert core.next_wake_ns() <= core.status_pacer.next_due_ns() <= last_ns + GAP
    statuses += run_until(core, last_ns + GAP)
    assert not statuses[-1].armed and statuses[-1].thrust_withheld == "disarmed"
    assert core.status_pacer.next_due_ns() is None


def test_the_last_state_of_a_burst_within_one_gap_is_said_at_its_end() -> None:
    core = connected()
    core.tick(at(2 * MS))
    t = 200 * MS
    run_until(core, t)
    (first,) = published(core.on_mavlink(heartbeat(armed=False), at(t)), VehicleStatus)
    assert not first.armed  # at once: the status was quiet
    for k in range(1, 100):  # 99 more within 10 ms, the last armed
        outs = core.on_mavlink(heartbeat(armed=k % 2 == 1), at(t + k * 100_000))
        assert not published(outs, VehicleStatus)
    assert core.status_pacer.next_due_ns() == t + GAP
    assert core.next_wake_ns() <= t + GAP  # the loop is told to wake for it
    assert not run_until(core, t + GAP - 1)
    (last,) = published(core.tick(at(t + GAP)), VehicleStatus)
    assert last.armed and last.thrust_withheld is None  # the latest state, not the first held


def test_a_single_change_after_quiet_is_said_at_once() -> None:
    core = connected()
    core.tick(at(2 * MS))
    run_until(core, 300 * MS)
    (st,) = published(core.on_mavlink(heartbeat(armed=False), at(300 * MS)), VehicleStatus)
    assert not st.armed  # in the same call's outputs
    # ... and the next one a gap later too
    (st,) = published(core.on_mavlink(heartbeat(armed=True), at(300 * MS + GAP)), VehicleStatus)
    assert st.armed


def test_a_link_loss_within_the_gap_is_said_by_its_end() -> None:
    """A status said at once just before the link is lost: the loss is held, not past the gap."""
    core = connected()
    core.tick(at(2 * MS))
    hb_ns = 1 * S
    run_until(core, hb_ns)
    core.on_mavlink(heartbeat(armed=True), at(hb_ns))
    loss_ns = hb_ns + round(core.cfg.heartbeat_timeout_s * 1e9)
    run_until(core, loss_ns - MS)
    # thrust commands fresh again just before the loss: said at once, a gap starts
    assert published(core.on_thrust(thrust(10.0, 10.0, loss_ns - MS), at(loss_ns - MS)),
                     VehicleStatus)
    outs = core.tick(at(loss_ns))
    assert not core.link.ok and not published(outs, VehicleStatus)  # held: within the gap
    assert core.next_wake_ns() <= core.status_pacer.next_due_ns() == loss_ns - MS + GAP
    (st,) = run_until(core, loss_ns - MS + GAP)
    assert not st.link_ok and st.thrust_withheld == "no_link"


# -- the node's timer ---------------------------------------------------------------------------------


def test_the_node_timer_wakes_when_another_thread_makes_work_due_sooner() -> None:
    """A status held back on the receive thread is due within the gap: the timer, asleep until the
    next work it knew of, is woken for it (``VehicleIoNode._wake_sooner``), not left to sleep on."""
    node = VehicleIoNode(VehicleIoConfig(mavlink="udpin:127.0.0.1:0"), LIM)
    node._wake_ns = time.monotonic_ns() + 60 * S  # the last tick: nothing due for a minute
    stop = threading.Event()
    sleeper = threading.Thread(target=node.sleep, args=(30.0, stop), daemon=True)
    sleeper.start()
    time.sleep(0.05)
    assert sleeper.is_alive()  # asleep
    with node.lock:
        node._wake_sooner()  # the core has work due now (a new core: everything)
    sleeper.join(5.0)
    assert not sleeper.is_alive()
    assert node._wake_ns == node.core.next_wake_ns()


def test_a_flapping_vehicle_is_worth_a_warning_and_a_change_held_now_and_then_is_not() -> None:
    """Ten changes held back within a minute: a flapping link or autopilot. One now and then (the
    link made, armed and the mode set within 50 ms): no news."""
    from seaway_vehicle_io.status_pacing import FLAPPING_HELD, FLAPPING_WINDOW_NS, FlapWatch

    s = 1_000_000_000
    quiet = FlapWatch()
    # One every 10 s for five minutes: six a minute, never ten.
    assert [quiet.look(held, held * 10 * s) for held in range(30)] == [None] * 30
    flapping = FlapWatch()
    assert flapping.look(0, 0) is None  # the window starts
    said = [flapping.look(held, held * 1_000_000) for held in range(1, 3 * FLAPPING_HELD)]
    assert said[:FLAPPING_HELD - 1] == [None] * (FLAPPING_HELD - 1)
    assert said[FLAPPING_HELD - 1] == FLAPPING_HELD  # the tenth within the window
    assert flapping.look(3 * FLAPPING_HELD - 1, 3 * FLAPPING_HELD * 1_000_000) is None  # no growth
    # A new window counts afresh.
    assert flapping.look(100, FLAPPING_WINDOW_NS) is None
    assert flapping.look(100 + FLAPPING_HELD - 1, FLAPPING_WINDOW_NS + s) is None
