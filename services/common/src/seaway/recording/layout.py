"""MCAP's record layouts (mcap.dev/spec): the one place Seaway spells them.

The recorder's writer (``seaway_recorder.mcapfile``) packs the records written per message and per
chunk with these; the reader (``seaway.recording.chunks``) unpacks a chunk's messages and the
summary's chunk indexes with them, faster than the mcap library's record classes. Sizes in bytes,
times in ns on the recording's timeline; every field little-endian, as the specification has it.
"""

from __future__ import annotations

import struct

from mcap.writer import MCAP0_MAGIC as MAGIC

__all__ = ["CHUNK_HEAD", "CHUNK_INDEX_HEAD", "FOOTER", "MAGIC", "MESSAGE_HEAD", "RECORD_HEAD", "U32",
           "U64"]

RECORD_HEAD = struct.Struct("<BQ")
"""Every record: its opcode and the length of what follows."""
MESSAGE_HEAD = struct.Struct("<HIQQ")
"""A Message after its record head: channel id, sequence, log time, publish time; the data follows."""
CHUNK_HEAD = struct.Struct("<QQQI")
"""A Chunk after its record head: start and end time, uncompressed size, uncompressed CRC; then the
compression's name (length-prefixed), the records' length (8 bytes) and the records."""
CHUNK_INDEX_HEAD = struct.Struct("<QQQQI")
"""A Chunk Index after its record head: start and end time, the chunk's offset and length, the
length of its map of message index offsets (10 bytes an entry: channel id, offset)."""
FOOTER = struct.Struct("<BQQQI")
"""The Footer record whole: opcode, length, summary start, summary offset start, summary CRC."""
U32, U64 = struct.Struct("<I"), struct.Struct("<Q")
