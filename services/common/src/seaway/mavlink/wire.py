"""MAVLink's frame layout as it is on the wire: what the simulator and vehicle_io both read off raw
frame bytes, before (or instead of) pymavlink parses them. Sizes in bytes."""

from __future__ import annotations

MAVLINK2_MAGIC = 0xFD
"""The first byte of a MAVLink 2 frame."""
MAVLINK1_MAGIC = 0xFE
"""The first byte of a MAVLink 1 frame."""
IFLAG_SIGNED = 0x01
"""MAVLink 2 incompatibility flag (the frame's third byte): a signature block follows the CRC."""
HEADER_LEN = 10
"""A MAVLink 2 header: magic, length, incompat and compat flags, sequence, system id, component id,
message id (3 bytes)."""
MAVLINK1_HEADER_LEN = 6
"""A MAVLink 1 header: magic, length, sequence, system id, component id, message id."""
CRC_LEN = 2
SIGNATURE_BLOCK_LEN = 13
"""A MAVLink 2 signature block: link id (1), timestamp (6), signature (6)."""


def frame_ids(frame: bytes) -> tuple[int | None, int | None]:
    """(system id, component id) claimed by the header of the first frame in ``frame``, without
    any check (None, None for bytes that do not start a MAVLink frame). For counting refusals."""
    if len(frame) >= HEADER_LEN and frame[0] == MAVLINK2_MAGIC:
        return frame[5], frame[6]
    if len(frame) >= MAVLINK1_HEADER_LEN and frame[0] == MAVLINK1_MAGIC:
        return frame[3], frame[4]
    return None, None
