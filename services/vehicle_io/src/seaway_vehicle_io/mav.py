"""The one place pymavlink is imported: MAVLink 2 framing, the ``ardupilotmega`` dialect.

The ``ardupilotmega`` dialect is a superset of ``common`` and decodes everything PX4 and ArduPilot
send that vehicle_io reads, once the messages in ``dialect/events.xml`` are added to it.
``MAVLINK20=1`` must be in the environment before ``pymavlink.mavutil`` is imported, otherwise
mavutil starts on MAVLink 1 framing and only switches after it has seen a MAVLink 2 packet; we want
our very first HEARTBEAT to be MAVLink 2 (MANUAL_CONTROL's extension fields need it).
"""

from __future__ import annotations

import os

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil  # (the environment above must come first)
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from seaway_vehicle_io.dialect import events as _extra

DIALECT = "ardupilotmega"

# The events protocol and COMPONENT_METADATA (PX4 says why it refuses to arm through them) are in
# MAVLink's common.xml but not in pymavlink's generated dialects: add them, never replacing one.
for _msg_id, _msg_type in _extra.mavlink_map.items():
    mavlink.mavlink_map.setdefault(_msg_id, _msg_type)

__all__ = ["DIALECT", "mavlink", "mavutil", "result_name"]


def result_name(result: int) -> str:
    """MAV_RESULT number -> name without the prefix, e.g. 1 -> 'TEMPORARILY_REJECTED'."""
    entry = mavlink.enums["MAV_RESULT"].get(result)
    if entry is None or entry.name.endswith("_ENUM_END"):
        return f"UNKNOWN_RESULT_{result}"
    return entry.name.removeprefix("MAV_RESULT_")
