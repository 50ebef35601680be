"""The operating area as the autopilot's own fence (``fence_plan``, ``fence_sync``), through the
core: the items and parameters sent, the read-back and its verdict, refusals naming the field,
re-syncs on a change, a new link or a reboot. The autopilot's side is a small fake mission server
answering with real packed MAVLink messages (pure logic: no sockets)."""

from __future__ import annotations

import logging
import math
from typing import Any

import pytest
from seaway.contract.messages import ActiveArea, VehicleStatus
from seaway.contract.units import NS_PER_S
from seaway.vessel.frames import GeoOrigin
from seaway_vehicle_io import fence_plan
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.core import Now, VehicleIoCore
from seaway_vehicle_io.fence_sync import SendParamRead, SendParamSet
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.mission_transfer import (
    MissionItem,
    SendMissionAck,
    SendMissionCount,
    SendMissionItemInt,
    SendMissionRequestInt,
    SendMissionRequestList,
)
from seaway_vehicle_io.thrust import ThrusterLimits

S = NS_PER_S
MS = 1_000_000
WALL0 = 1_800_000_000 * S
ORIGIN = GeoOrigin.from_degrees(28.18, 112.94, 30.0)
LIM = ThrusterLimits(75.0, 75.0, 0.0)
AUTOPILOTS = {"ardupilot": (mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 11),
              "px4": (mavlink.MAV_AUTOPILOT_PX4, 1)}


def wire(msg: Any, sysid: int = 1) -> Any:
    tx = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(tx)))


def at(t_ns: int) -> Now:
    return Now(WALL0 + t_ns, t_ns)


def area(since_ns: int = 1, keep_in: int = 4, circle_m: float = 20.0, rally: int = 2,
         half_m: float = 200.0) -> ActiveArea:
    square = [(half_m * math.cos(a), half_m * math.sin(a))
              for a in (2 * math.pi * k / keep_in + 0.1 for k in range(keep_in))]
    return ActiveArea.make(
        stamp_ns=since_ns, since_ns=since_ns, source="test",
        keep_in={"name": "lake", "vertices": [{"x_m": x, "y_m": y} for x, y in square]},
        keep_out_polygons=[{"vertices": [{"x_m": 50, "y_m": 50}, {"x_m": 50, "y_m": 70},
                                         {"x_m": 70, "y_m": 60}]}],
        keep_out_circles=[{"name": "buoy", "x_m": -60, "y_m": -40, "radius_m": circle_m}],
        rally_points=[{"x_m": -20.0 * (k + 1), "y_m": 30.0} for k in range(rally)])


class FakeAutopilot:
    """Stores what is uploaded, answers downloads and parameters: an ArduPilot or PX4 seen from the
    mission protocol. ``max_items``: NO_SPACE above it; ``drift``: stored latitudes off by this."""

    def __init__(self, kind: str, max_items: int = 1000, drift: int = 0,
                 param_override: dict[str, float] | None = None, mute: bool = False) -> None:
        self.kind, self.max_items, self.drift, self.mute = kind, max_items, drift, mute
        self.stored: dict[int, list[MissionItem]] = {}
        self.params: dict[str, float] = {}
        self.param_override = param_override or {}
        self._incoming: dict[int, list[MissionItem | None]] = {}
        self.sent_types: list[str] = []

    def heartbeat(self) -> Any:
        ap, mode = AUTOPILOTS[self.kind]
        return wire(mavlink.MAVLink_heartbeat_message(11, ap, 1, mode if self.kind == "ardupilot"
                                                      else (1 << 16), 3, 3))

    def answer(self, out: Any) -> list[Any]:
        self.sent_types.append(type(out).__name__)
        if self.mute:
            return []
        if isinstance(out, SendMissionCount):
            if out.count > self.max_items:
                return [wire(mavlink.MAVLink_mission_ack_message(
                    245, 191, mavlink.MAV_MISSION_NO_SPACE, out.mission_type))]
            self._incoming[out.mission_type] = [None] * out.count
            if out.count == 0:
                self.stored[out.mission_type] = []
                return [wire(mavlink.MAVLink_mission_ack_message(245, 191, 0, out.mission_type))]
            return [wire(mavlink.MAVLink_mission_request_int_message(245, 191, 0, out.mission_type))]
        if isinstance(out, SendMissionItemInt):
            got = self._incoming[out.mission_type]
            got[out.seq] = out.item
            if out.seq + 1 < len(got):
                return [wire(mavlink.MAVLink_mission_request_int_message(
                    245, 191, out.seq + 1, out.mission_type))]
            self.stored[out.mission_type] = [
                MissionItem(i.command, i.frame, i.param1, i.lat_e7 + self.drift, i.lon_e7, i.z)
                for i in got if i is not None]
            return [wire(mavlink.MAVLink_mission_ack_message(245, 191, 0, out.mission_type))]
        if isinstance(out, SendMissionRequestList):
            n = len(self.stored.get(out.mission_type, []))
            return [wire(mavlink.MAVLink_mission_count_message(245, 191, n, out.mission_type))]
        if isinstance(out, SendMissionRequestInt):
            i = self.stored[out.mission_type][out.seq]
            return [wire(mavlink.MAVLink_mission_item_int_message(
                245, 191, out.seq, i.frame, i.command, 0, 1, i.param1, 0, 0, 0, i.lat_e7, i.lon_e7,
                i.z, out.mission_type))]
        if isinstance(out, SendParamSet):
            self.params[out.param_id] = self.param_override.get(out.param_id, out.value)
            return [self._param_value(out.param_id, out.param_type)]
        if isinstance(out, SendParamRead) and out.param_id in self.params:
            return [self._param_value(out.param_id, 6 if self.kind == "px4" else 2)]
        return []

    def _param_value(self, name: str, param_type: int) -> Any:
        return wire(mavlink.MAVLink_param_value_message(name.encode(), self.params[name],
                                                        param_type, 900, 1))


MISSION_OUTPUTS = (SendMissionCount, SendMissionItemInt, SendMissionRequestInt,
                   SendMissionRequestList, SendMissionAck, SendParamSet, SendParamRead)


class Rig:
    """The core connected to a fake autopilot, with the area and the origin set."""

    def __init__(self, ap: FakeAutopilot, origin: GeoOrigin | None = ORIGIN) -> None:
        self.ap = ap
        self.t = 0
        self.core = VehicleIoCore(VehicleIoConfig(autopilot="auto", check_failsafe_params=False,
                                                  message_rates_hz={}, autopilot_events=False),
                                  LIM, at(0))
        assert self.core.fence is not None
        if origin is not None:
            self.core.fence.set_origin(origin)
        self.feed([ap.heartbeat()])

    def feed(self, msgs: list[Any]) -> None:
        pending = list(msgs)
        while pending:
            out = self.core.on_mavlink(pending.pop(0), at(self.t))
            pending += [m for o in out if isinstance(o, MISSION_OUTPUTS) for m in self.ap.answer(o)]

    def run(self, seconds: float, step_ms: int = 100) -> None:
        end = self.t + round(seconds * S)
        while self.t < end:
            self.t += step_ms * MS
            if self.t % S < step_ms * MS:
                self.feed([self.ap.heartbeat()])
            out = self.core.tick(at(self.t))
            self.feed([m for o in out if isinstance(o, MISSION_OUTPUTS) for m in self.ap.answer(o)])

    def status(self) -> VehicleStatus:
        return VehicleStatus.decode(self.core.status(at(self.t)).encode())


@pytest.mark.parametrize("kind", ["ardupilot", "px4"])
def test_the_area_is_uploaded_with_its_action_and_verified_by_reading_it_back(kind, caplog):
    rig = Rig(FakeAutopilot(kind))
    assert rig.core.fence is not None
    rig.core.fence.set_area(area())
    with caplog.at_level(logging.INFO):
        rig.run(1.0)
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "verified", st
    assert (st.fence_items, st.rally_points) == (4 + 3 + 1, 2)
    fence = rig.ap.stored[mavlink.MAV_MISSION_TYPE_FENCE]
    assert [i.command for i in fence] == [5001] * 4 + [5002] * 3 + [5004]
    assert [i.param1 for i in fence] == [4.0] * 4 + [3.0] * 3 + [20.0]
    lat, lon, _ = ORIGIN.to_geodetic(-60, -40)  # the circle's centre, independently
    assert fence[-1].lat_e7 == round(math.degrees(lat) * 1e7)
    assert fence[-1].lon_e7 == round(math.degrees(lon) * 1e7)
    rally = rig.ap.stored[mavlink.MAV_MISSION_TYPE_RALLY]
    assert [i.command for i in rally] == [mavlink.MAV_CMD_NAV_RALLY_POINT] * 2
    if kind == "ardupilot":
        assert rig.ap.params == {"FENCE_TYPE": 4.0, "FENCE_ACTION": 2.0, "FENCE_ENABLE": 1.0}
        assert rig.ap.sent_types.index("SendParamSet") > rig.ap.sent_types.index("SendMissionItemInt")
        assert "FENCE_ACTION=2 (Hold)" in st.action
    else:
        assert list(rig.ap.params) == ["GF_ACTION"]
        assert fence_plan.FENCES["px4"].enable[0].wire_value() == pytest.approx(2.8e-45, rel=0.01)
    assert "holds the operating area as its fence" in caplog.text


def test_the_same_area_published_again_is_not_uploaded_again_but_a_changed_one_is():
    rig = Rig(FakeAutopilot("ardupilot"))
    assert rig.core.fence is not None
    rig.core.fence.set_area(area(since_ns=1))
    rig.run(1.0)
    n = rig.ap.sent_types.count("SendMissionCount")
    rig.core.fence.set_area(area(since_ns=5))  # same geometry, re-published
    rig.run(1.0)
    assert rig.ap.sent_types.count("SendMissionCount") == n
    rig.core.fence.set_area(area(since_ns=9, circle_m=35.0))
    rig.run(1.0)
    assert rig.ap.sent_types.count("SendMissionCount") == n + 2
    assert rig.ap.stored[mavlink.MAV_MISSION_TYPE_FENCE][-1].param1 == 35.0
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "verified" and st.area_since_ns == 9


def test_a_fence_held_differently_is_a_mismatch_said_at_warning(caplog):
    rig = Rig(FakeAutopilot("ardupilot", drift=5, param_override={"FENCE_ACTION": 0.0}))
    assert rig.core.fence is not None
    rig.core.fence.set_area(area())
    with caplog.at_level(logging.WARNING):
        rig.run(1.0)
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "mismatch"
    assert "fence item 0: at" in st.detail and "FENCE_ACTION = 0, set to 2 (Hold)" in st.detail
    assert "DIFFERS from the operating area" in caplog.text


def test_more_vertices_than_px4_stores_is_refused_naming_the_fields_and_nothing_is_sent(caplog):
    rig = Rig(FakeAutopilot("px4"))
    assert rig.core.fence is not None
    rig.core.fence.set_area(area(keep_in=70, half_m=400))
    with caplog.at_level(logging.WARNING):
        rig.run(1.0)
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "refused"
    assert "keep_in (70 vertices)" in st.detail and "more than px4 stores (64" in st.detail
    assert "SendMissionCount" not in rig.ap.sent_types
    assert "cannot be the autopilot's fence" in caplog.text


def test_an_autopilot_out_of_fence_storage_is_a_refusal_naming_the_fields_not_retried():
    rig = Rig(FakeAutopilot("ardupilot", max_items=6))
    assert rig.core.fence is not None
    rig.core.fence.set_area(area())
    rig.run(30.0, step_ms=500)
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "refused"
    assert st.detail.startswith("fence upload refused by the autopilot: NO_SPACE")
    assert "keep_in (4 vertices) + keep_out_polygons (1, 3 vertices) + keep_out_circles (1)" in st.detail
    assert rig.ap.sent_types.count("SendMissionCount") == 1
    assert "SendParamSet" not in rig.ap.sent_types  # the fence is not enabled half-uploaded


def test_a_silent_autopilot_fails_the_sync_and_it_is_tried_again():
    ap = FakeAutopilot("ardupilot", mute=True)
    rig = Rig(ap)
    assert rig.core.fence is not None
    rig.core.fence.set_area(area())
    rig.run(8.0)
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "failed"
    assert "no answer to MISSION_COUNT 8 after 5 attempts" in st.detail
    assert ap.sent_types.count("SendMissionCount") == 5
    ap.mute = False
    rig.run(12.0)
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "verified"


def test_a_new_link_checks_the_fence_again():
    rig = Rig(FakeAutopilot("ardupilot"))
    assert rig.core.fence is not None
    rig.core.fence.set_area(area())
    rig.run(1.0)
    n = rig.ap.sent_types.count("SendMissionCount")
    rig.t += 10 * S  # silence: the link is lost
    rig.core.tick(at(rig.t))
    assert not rig.core.link.ok
    rig.run(1.0)  # the autopilot back (heartbeats): a new link
    assert rig.ap.sent_types.count("SendMissionCount") == n + 2
    assert rig.status().autopilot_fence.state == "verified"  # type: ignore[union-attr]


def test_nothing_is_sent_without_an_origin_or_with_the_fence_turned_off():
    rig = Rig(FakeAutopilot("ardupilot"), origin=None)
    assert rig.core.fence is not None
    rig.core.fence.set_area(area())
    rig.run(1.0)
    assert "SendMissionCount" not in rig.ap.sent_types
    assert rig.status().autopilot_fence is None
    off = VehicleIoCore(VehicleIoConfig(autopilot_fence=False), LIM, at(0))
    assert off.fence is None and off.status(at(0)).autopilot_fence is None


def test_an_empty_area_clears_the_fence_and_disables_ardupilots():
    rig = Rig(FakeAutopilot("ardupilot"))
    assert rig.core.fence is not None
    rig.core.fence.set_area(ActiveArea.make(stamp_ns=1, since_ns=1))
    rig.run(1.0)
    assert rig.ap.stored[mavlink.MAV_MISSION_TYPE_FENCE] == []
    assert rig.ap.params == {"FENCE_ENABLE": 0.0}
    assert rig.status().autopilot_fence.state == "verified"  # type: ignore[union-attr]


def test_a_reboot_without_the_link_dropping_checks_the_fence_again():
    """A fast reboot (SYSTEM_TIME going back, the link never lost): the autopilot's fence is
    uploaded and read back again, since a firmware may come back without it."""
    rig = Rig(FakeAutopilot("ardupilot"))
    assert rig.core.fence is not None
    rig.core.fence.set_area(area())
    rig.feed([wire(mavlink.MAVLink_system_time_message(WALL0 // 1000, 600_000))])
    rig.run(1.0)
    n = rig.ap.sent_types.count("SendMissionCount")
    rig.feed([wire(mavlink.MAVLink_system_time_message(WALL0 // 1000, 2_000))])  # rebooted
    rig.run(1.0)
    assert rig.ap.sent_types.count("SendMissionCount") == n  # not yet proven
    rig.feed([wire(mavlink.MAVLink_system_time_message(WALL0 // 1000, 3_000))])  # it was
    assert rig.core.link.ok
    rig.run(1.0)
    assert rig.ap.sent_types.count("SendMissionCount") == n + 2
    assert rig.status().autopilot_fence.state == "verified"  # type: ignore[union-attr]


def test_px4_discarding_a_zone_it_accepted_is_a_mismatch_not_verified(caplog):
    """PX4's navigator drops a zone that does not contain home after the upload was ACKed, and
    says so only in text: the lists still read back as uploaded."""
    rig = Rig(FakeAutopilot("px4"))
    assert rig.core.fence is not None
    rig.core.fence.set_area(area())
    rig.run(1.0)
    assert rig.status().autopilot_fence.state == "verified"  # type: ignore[union-attr]
    with caplog.at_level(logging.WARNING):
        rig.feed([wire(mavlink.MAVLink_statustext_message(
            mavlink.MAV_SEVERITY_CRITICAL, b"Geofence invalid, doesn't contain Home position"))])
    st = rig.status().autopilot_fence
    assert st is not None and st.state == "mismatch"
    assert "does not enforce all of it" in st.detail and "Home position" in st.detail
    assert "DIFFERS" in caplog.text
    rig.core.fence.set_area(area(since_ns=7, circle_m=30.0))  # a new area: judged afresh
    rig.run(1.0)
    assert rig.status().autopilot_fence.state == "verified"  # type: ignore[union-attr]
