"""MAVLink's mission protocol, one transfer (``mission_transfer``): uploads answered in any order,
refusals, timeouts and retries, downloads with repeats; real packed MAVLink messages, time passed in."""

from __future__ import annotations

from typing import Any

from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.mission_transfer import (
    MissionItem,
    SendMissionAck,
    SendMissionCount,
    SendMissionItemInt,
    SendMissionRequestInt,
    SendMissionRequestList,
    Transfer,
    mission_result_name,
)

MS = 1_000_000
FENCE = mavlink.MAV_MISSION_TYPE_FENCE
RALLY = mavlink.MAV_MISSION_TYPE_RALLY
TIMEOUT = 1500 * MS
ITEMS = tuple(MissionItem(mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 0, 3.0,
                          281800000 + i, 1129400000 + i) for i in range(3))


def wire(msg: Any) -> Any:
    tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(tx)))


def request(seq: int, mission_type: int = FENCE, legacy: bool = False) -> Any:
    if legacy:
        return wire(mavlink.MAVLink_mission_request_message(245, 191, seq, mission_type))
    return wire(mavlink.MAVLink_mission_request_int_message(245, 191, seq, mission_type))


def ack(result: int, mission_type: int = FENCE) -> Any:
    return wire(mavlink.MAVLink_mission_ack_message(245, 191, result, mission_type))


def count(n: int, mission_type: int = FENCE) -> Any:
    return wire(mavlink.MAVLink_mission_count_message(245, 191, n, mission_type))


def item(seq: int, it: MissionItem, mission_type: int = FENCE) -> Any:
    return wire(mavlink.MAVLink_mission_item_int_message(
        245, 191, seq, it.frame, it.command, 0, 1, it.param1, 0, 0, 0, it.lat_e7, it.lon_e7, it.z,
        mission_type))


def upload(items: tuple[MissionItem, ...] = ITEMS, attempts: int = 3) -> Transfer:
    return Transfer((1, 1), FENCE, TIMEOUT, attempts, upload=items)


def test_an_upload_answers_each_request_in_any_order_and_ends_on_the_ack():
    t = upload()
    assert t.start(0) == [SendMissionCount(1, 1, 3, FENCE)]
    sent = []
    for k, seq in enumerate((0, 2, 1, 1)):  # out of order, one asked twice, one as MISSION_REQUEST
        sent += t.on_mavlink(request(seq, legacy=k == 1), k * MS)
    assert [s.seq for s in sent] == [0, 2, 1, 1]
    assert all(isinstance(s, SendMissionItemInt) and s.item == ITEMS[s.seq] for s in sent)
    assert t.result is None
    t.on_mavlink(ack(mavlink.MAV_MISSION_ACCEPTED), 5 * MS)
    assert t.result == "ok"


def test_an_accepted_ack_before_every_item_was_asked_for_is_not_the_end():
    t = upload()
    t.start(0)
    t.on_mavlink(request(0), MS)
    t.on_mavlink(ack(mavlink.MAV_MISSION_ACCEPTED), 2 * MS)  # left over from an earlier transfer
    assert t.result is None


def test_a_refusal_ends_the_upload_with_the_autopilots_result_name():
    t = upload()
    t.start(0)
    t.on_mavlink(ack(mavlink.MAV_MISSION_NO_SPACE), MS)
    assert t.result == "fence upload refused by the autopilot: NO_SPACE"
    assert mission_result_name(99) == "UNKNOWN_RESULT_99"


def test_messages_of_another_mission_type_are_not_this_transfers():
    t = upload()
    t.start(0)
    assert t.on_mavlink(request(0, RALLY), MS) == []
    t.on_mavlink(ack(mavlink.MAV_MISSION_NO_SPACE, RALLY), MS)
    assert t.result is None


def test_silence_resends_the_last_message_then_fails_saying_what_it_waited_for():
    t = upload(attempts=3)
    t.start(0)
    assert t.tick(TIMEOUT - 1) == []
    assert t.tick(TIMEOUT) == [SendMissionCount(1, 1, 3, FENCE)]
    assert t.next_due_ns() == 2 * TIMEOUT
    assert t.tick(2 * TIMEOUT) == [SendMissionCount(1, 1, 3, FENCE)]
    assert t.tick(3 * TIMEOUT) == []
    assert t.result == "fence upload: no answer to MISSION_COUNT 3 after 3 attempts of 1.5 s"


def test_a_request_after_a_silence_resets_the_retries():
    t = upload(attempts=2)
    t.start(0)
    t.tick(TIMEOUT)  # MISSION_COUNT again (2 of 2)
    out = t.on_mavlink(request(0), TIMEOUT + MS)
    assert [o.seq for o in out] == [0]
    assert t.tick(2 * TIMEOUT + MS) == out  # the item in flight, not the count
    assert t.result is None


def test_a_request_beyond_the_list_ends_the_upload():
    t = upload()
    t.start(0)
    out = t.on_mavlink(request(7), MS)
    assert out == [SendMissionAck(1, 1, mavlink.MAV_MISSION_INVALID_SEQUENCE, FENCE)]
    assert t.result is not None and "item 7 of 3" in t.result


def test_an_empty_upload_clears_the_list():
    t = upload(items=())
    assert t.start(0) == [SendMissionCount(1, 1, 0, FENCE)]
    t.on_mavlink(ack(mavlink.MAV_MISSION_ACCEPTED), MS)
    assert t.result == "ok"


def test_a_download_asks_item_by_item_ignores_repeats_and_acks_at_the_end():
    t = Transfer((1, 1), FENCE, TIMEOUT, 3)
    assert t.start(0) == [SendMissionRequestList(1, 1, FENCE)]
    assert t.tick(TIMEOUT) == [SendMissionRequestList(1, 1, FENCE)]  # no MISSION_COUNT yet
    assert t.on_mavlink(count(3), TIMEOUT + MS) == [SendMissionRequestInt(1, 1, 0, FENCE)]
    assert t.on_mavlink(item(0, ITEMS[0]), TIMEOUT + 2 * MS) == [SendMissionRequestInt(1, 1, 1, FENCE)]
    assert t.on_mavlink(item(0, ITEMS[0]), TIMEOUT + 3 * MS) == []  # a repeat
    assert t.on_mavlink(item(2, ITEMS[2]), TIMEOUT + 3 * MS) == []  # out of order
    assert t.tick(2 * TIMEOUT + 2 * MS) == [SendMissionRequestInt(1, 1, 1, FENCE)]  # lost: again
    t.on_mavlink(item(1, ITEMS[1]), 2 * TIMEOUT + 3 * MS)
    out = t.on_mavlink(item(2, ITEMS[2]), 2 * TIMEOUT + 4 * MS)
    assert out == [SendMissionAck(1, 1, mavlink.MAV_MISSION_ACCEPTED, FENCE)]
    assert t.result == "ok" and tuple(t.items) == ITEMS
    assert t.tick(10 * TIMEOUT) == []


def test_an_empty_download_is_done_at_its_count():
    t = Transfer((1, 1), RALLY, TIMEOUT, 3)
    t.start(0)
    assert t.on_mavlink(count(0, RALLY), MS) == [
        SendMissionAck(1, 1, mavlink.MAV_MISSION_ACCEPTED, RALLY)]
    assert t.result == "ok" and t.items == []
