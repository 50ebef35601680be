"""The autopilot vehicle_io is locked to (an authorised, correctly signed source) sending well-formed
MAVLink with absurd values or at absurd rates: nothing grows without bound, the log is not
flooded, and nothing absurd is taken for true. Pure core, real packed messages, time passed in."""

from __future__ import annotations

import logging
import math
import tracemalloc
from typing import Any

import pytest
from seaway.contract.messages import GnssFix, VehicleStatus
from seaway_vehicle_io.autopilot_events import REPORT_FAILURES_KEPT, EventTracker
from seaway_vehicle_io.changelog import BURST
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.mission_transfer import MissionItem
from seaway_vehicle_io.status_pacing import MIN_STATUS_GAP_NS

from tests.unit.vehicle_io import test_fence_sync as fence
from tests.unit.vehicle_io.test_core import (
    MS,
    S,
    at,
    attitude,
    connected,
    global_position_int,
    heartbeat,
    make,
    published,
    wire,
)
from tests.unit.vehicle_io.test_px4_events import CATALOG, MANUAL, args, eid

PX4_MANUAL = 1 << 16
PX4_HOLD = (4 << 16) | (3 << 24)
LOGGER = "seaway.vehicle_io"


def statustext(text: str, severity: int = 6, text_id: int = 0, chunk_seq: int = 0) -> Any:
    return wire(mavlink.MAVLink_statustext_message(severity, text.encode(), text_id, chunk_seq))


def lines(caplog, level: int | None = None) -> list[logging.LogRecord]:
    return [r for r in caplog.records if r.name == LOGGER and (level is None or r.levelno == level)]


# -- values at and beyond the field's range -------------------------------------------------------


@pytest.mark.parametrize(("lat", "lon", "published_ok"), [
    (900_000_000, 1_800_000_000, True),  # exactly the poles and the antimeridian: valid
    (-900_000_000, -1_800_000_000, True),
    (900_000_001, 0, False),
    (2**31 - 1, 2**31 - 1, False),  # int32 extremes
    (-(2**31), -(2**31), False),
])
def test_positions_at_and_beyond_the_poles(lat: int, lon: int, published_ok: bool) -> None:
    """At the bound, the fix is published within the contract's [-pi/2, pi/2] x [-pi, pi] (float
    rounding must not put it a hair outside and fail the message's construction); beyond, the
    message is dropped and counted, not published."""
    core = connected()
    fixes = published(core.on_mavlink(global_position_int(1000, lat=lat, lon=lon), at(10 * MS)),
                      GnssFix)
    if published_ok:
        (fix,) = fixes
        assert abs(fix.lat_rad) == math.pi / 2 and abs(fix.lon_rad) == math.pi
        assert core.dropped == 0
    else:
        assert fixes == [] and core.dropped == 1


# -- memory ------------------------------------------------------------------------------------------


def test_chunked_texts_never_finished_do_not_pile_up() -> None:
    """STATUSTEXT chunks (``id`` != 0) whose last chunk never comes were kept per id until the
    link dropped: 65535 ids of 7 chunks held about 58 MB. Now only the few newest unfinished
    texts are kept, and a text whose chunks come back to back is still joined."""
    core = connected()
    first = statustext("x" * 50, text_id=1)  # one full-length chunk: the text goes on
    core.on_mavlink(first, at(2 * MS))
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        for i in range(2, 20_002):
            core.on_mavlink(statustext(f"{i:05d}".ljust(50, "y"), text_id=i), at(3 * MS + i * 10_000))
        grown = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert grown < 500_000, grown  # before: about 5 MB for these 20,000 unfinished texts
    core.on_mavlink(statustext("PreArm: " + "a" * 42, severity=2, text_id=30_000), at(S))
    core.on_mavlink(statustext("still joined", severity=2, text_id=30_000, chunk_seq=1), at(S))
    assert [t.text for t in core.texts.since(S)] == ["PreArm: " + "a" * 42 + "still joined"]


def test_an_arming_report_never_finished_does_not_grow() -> None:
    """PX4 lists an arming-check report's failures after its summary; failures kept coming with
    no new summary grew the report without bound (100,000 events: 100,000 kept). It keeps the
    first ``REPORT_FAILURES_KEPT``, and the refusal still names them."""
    t = EventTracker(CATALOG)
    t.on_event(eid(300), args("I", 0), 0x88, 1, 0)  # the summary
    for k in range(10_000):
        t.on_event(eid(301), args("IB", 1, 17), 0x33, (2 + k) & 0xFFFF, k)
    assert t.report is not None and len(t.report.failures) == REPORT_FAILURES_KEPT
    assert t.refusal(0, MANUAL)[0] == ["No heading reference"]


# -- the log ---------------------------------------------------------------------------------------


def test_the_autopilots_ever_new_texts_do_not_silence_drop_warnings(caplog) -> None:
    """Texts were logged under their own text as the rate limiter's key, in the table the drop
    warnings use (256 keys, then one shared budget): after 300 texts with a number in them, a NaN
    attitude was dropped without a line. The texts have a table of their own now."""
    caplog.set_level(logging.INFO, LOGGER)
    core = connected()
    for i in range(300):
        core.on_mavlink(statustext(f"EKF variance {i}"), at(2 * MS + i * 10 * MS))
    core.on_mavlink(attitude(time_boot_ms=1000), at(3100 * MS))
    caplog.clear()
    core.on_mavlink(attitude(time_boot_ms=1200, roll=float("nan")), at(3300 * MS))
    assert core.dropped == 1
    (rec,) = lines(caplog, logging.WARNING)
    assert "ATTITUDE" in rec.getMessage() and "roll" in rec.getMessage()


def test_a_broken_frame_before_the_link_is_counted_not_warned(caplog) -> None:
    """A stream joined mid-frame (ArduPilot SITL's TCP port gave one "Bad prefix" at every
    connect) is counted and said at INFO; once the link is up and the autopilot has started
    (``test_autopilot_start``), a broken frame is a warning."""
    caplog.set_level(logging.INFO, LOGGER)
    core = make(check_failsafe_params=False)
    bad = mavlink.MAVLink_bad_data(b"\x01\x02", "Bad prefix")
    core.on_mavlink(bad, at(0))
    assert core.dropped == 1 and not lines(caplog, logging.WARNING)
    assert any("BAD_DATA" in r.getMessage() for r in lines(caplog, logging.INFO))
    core.on_mavlink(heartbeat(armed=False), at(1 * MS))
    assert core.link.ok
    core.on_mavlink(wire(mavlink.MAVLink_sys_status_message(0, 0, 0, 0, 12000, 0, 100, 0, 0, 0, 0,
                                                            0, 0)), at(2 * MS))  # healthy: started
    core.on_mavlink(wire(mavlink.MAVLink_estimator_status_message(0, 0x7 | 16, 0, 0, 0, 0, 0, 0, 0,
                                                                  0)), at(3 * MS))
    core.status(at(S))  # healthy from here: started after READY_SETTLE_S
    caplog.clear()
    core.on_mavlink(heartbeat(armed=False), at(6 * S - MS))
    core.on_mavlink(bad, at(6 * S))  # past the 5 s the log limits a kind to one line
    (rec,) = lines(caplog, logging.WARNING)
    assert core.dropped == 2 and "BAD_DATA" in rec.getMessage()


def test_an_autopilot_flapping_its_mode_is_followed_but_not_a_flood_of_lines(caplog) -> None:
    """10,000 HEARTBEATs in a second alternating MANUAL and HOLD, armed: every one was a line
    (10,000 INFO). The state still follows each HEARTBEAT (and what the thrusters do is published
    at most once per ``MIN_STATUS_GAP_NS``: ``test_status_pacing``); the log says the first
    ``BURST`` changes, then, when the window ends, the latest with the count."""
    caplog.set_level(logging.INFO, LOGGER)
    core = connected()
    caplog.clear()
    statuses = 0
    for i in range(10_000):
        hb = heartbeat(armed=True, custom_mode=PX4_HOLD if i % 2 == 0 else PX4_MANUAL)
        statuses += len(published(core.on_mavlink(hb, at(2 * MS + i * 100_000)), VehicleStatus))
        assert core.link.mode == ("HOLD" if i % 2 == 0 else "MANUAL")
    assert statuses <= S // MIN_STATUS_GAP_NS + 1  # withheld "mode" <-> None: paced, not 10,000
    assert len(lines(caplog, logging.INFO)) == BURST
    core.tick(at(6 * S))  # the window is over: the latest change, with the count
    summary = lines(caplog, logging.INFO)[-1].getMessage()
    assert "MANUAL" in summary and str(10_000 - BURST) in summary


def test_an_autopilot_flapping_its_health_is_not_a_flood_of_lines(caplog) -> None:
    """HEARTBEAT ``system_status`` alternating ACTIVE and CRITICAL while armed in MANUAL: the
    health problem was a line per message (5,000 WARNING + 4,999 INFO for 10,000)."""
    caplog.set_level(logging.INFO, LOGGER)
    core = connected()
    caplog.clear()
    for i in range(10_000):
        hb = wire(mavlink.MAVLink_heartbeat_message(10, 12, 1 | 128, PX4_MANUAL,
                                                    5 if i % 2 == 0 else 4, 3))
        core.on_mavlink(hb, at(2 * MS + i * 100_000))
    assert len(lines(caplog)) <= BURST
    assert core.status(at(S)).thrust_withheld is None  # the last said ACTIVE: healthy


def test_real_changes_close_together_are_each_logged(caplog) -> None:
    """What the limit must not cost: a few genuine changes within a second each get their line."""
    caplog.set_level(logging.INFO, LOGGER)
    core = connected(armed=False)
    caplog.clear()
    core.on_mavlink(heartbeat(armed=False, custom_mode=PX4_HOLD), at(100 * MS))
    core.on_mavlink(heartbeat(armed=False, custom_mode=PX4_MANUAL), at(200 * MS))
    core.on_mavlink(heartbeat(armed=True, custom_mode=PX4_MANUAL), at(300 * MS))
    said = [r.getMessage() for r in lines(caplog, logging.INFO)]
    assert len(said) == 3 and "HOLD" in said[0] and "ARMED" in said[2]


# -- the fence read back --------------------------------------------------------------------------


class NanFenceAutopilot(fence.FakeAutopilot):
    """Reads its fence back with every param1 (vertex count, circle radius) NaN."""

    def answer(self, out: Any) -> list[Any]:
        replies = super().answer(out)
        for kind, items in self.stored.items():
            self.stored[kind] = [MissionItem(i.command, i.frame, math.nan, i.lat_e7, i.lon_e7, i.z)
                                 for i in items]
        return replies


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_a_fence_read_back_with_nan_is_a_mismatch_not_verified(kind: str) -> None:
    """``abs(NaN - 20.0) > 0.01`` is False: a fence held with NaN radii and vertex counts was
    reported ``verified``."""
    rig = fence.Rig(NanFenceAutopilot(kind))
    assert rig.core.fence is not None
    rig.core.fence.set_area(fence.area())
    rig.run(1.0)
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "mismatch"
    assert "param1 nan" in st.detail
