"""A replay's frames, kept out of memory: appended in time order, held as zlib-compressed blocks in an
unnamed temporary file, and read back a bounded span at a time (``timeline.py`` fills one).

Why: the frames of a recording are some 50 times its size (an hour of one vessel at 10 Hz, 5 MB of
MCAP, is 65 MB of frames' JSON), and a ground station keeps a few recordings open at once. Here
memory holds 16 bytes per frame (its time and where its text ends) and the last block being
filled (``BLOCK_BYTES``); the disk holds the rest, compressed (about 1/10 to 1/20 of it; the file
has no name, so it goes when the store does, or the process). An answer is at most ``max_bytes``
of frames: a whole recording is never one body.
"""

from __future__ import annotations

import bisect
import json
import os
import tempfile
import threading
import zlib
from array import array
from typing import IO

from seaway_groundstation.replay import ReplayFrame

BLOCK_BYTES = 1 << 20
"""Frames' text compressed and written out together [bytes]; also what stays in memory at most."""
_LEVEL = 1
"""zlib level: the fastest; frames' JSON repeats its keys, so even it compresses some 10 times."""


class FrameStore:
    """Frames in time order, their text on disk; see the module's description. Thread-safe: one
    thread appends while others read."""

    def __init__(self, block_bytes: int = BLOCK_BYTES) -> None:
        self.block_bytes = block_bytes
        self.times = array("d")
        """Each frame's ``t_s`` [s since the recording's start], in time order."""
        self._ends = array("q")  # where each frame's item ends in the uncompressed text [bytes]
        self._block_starts = array("q")  # where each block starts in the uncompressed text [bytes]
        self._block_at = array("q")  # where each block starts in the file [bytes]
        self._block_len = array("q")  # its compressed length [bytes]
        self._tail = bytearray()  # the items not yet in a block
        self._tail_start = 0  # where the tail starts in the uncompressed text [bytes]
        self._file: IO[bytes] | None = None
        self._file_bytes = 0
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self.times)

    @property
    def disk_bytes(self) -> int:
        """Compressed bytes written to the temporary file so far [bytes]."""
        return self._file_bytes

    def append(self, frames: list[ReplayFrame]) -> None:
        """Frames later than (or as late as) every one appended before."""
        with self._lock:
            for f in frames:
                if self.times and f.t_s < self.times[-1]:
                    raise ValueError(f"frame at {f.t_s} s after one at {self.times[-1]} s")
                # Each item ends with a comma: a span of them is a JSON array's inside, but the last.
                item = f'{{"t_s":{json.dumps(f.t_s)},"frame":{f.frame}}},'.encode()
                self._tail += item
                self.times.append(f.t_s)
                self._ends.append(self._tail_start + len(self._tail))
            if len(self._tail) >= self.block_bytes:
                self._flush()

    def _flush(self) -> None:
        if self._file is None:
            self._file = tempfile.TemporaryFile(prefix="seaway-gs-replay-")  # noqa: SIM115 - kept
        data = zlib.compress(bytes(self._tail), _LEVEL)
        os.pwrite(self._file.fileno(), data, self._file_bytes)
        self._block_starts.append(self._tail_start)
        self._block_at.append(self._file_bytes)
        self._block_len.append(len(data))
        self._file_bytes += len(data)
        self._tail_start += len(self._tail)
        self._tail = bytearray()

    def _text(self, start: int, end: int) -> bytes:
        """The uncompressed text's bytes ``[start, end)``; the caller holds the lock."""
        parts: list[bytes] = []
        i = max(0, bisect.bisect_right(self._block_starts, start) - 1)
        while i < len(self._block_starts) and self._block_starts[i] < end:
            assert self._file is not None
            raw = zlib.decompress(os.pread(self._file.fileno(), self._block_len[i], self._block_at[i]))
            b0 = self._block_starts[i]
            parts.append(raw[max(0, start - b0):end - b0])
            i += 1
        if end > self._tail_start:
            parts.append(bytes(self._tail[max(0, start - self._tail_start):end - self._tail_start]))
        return b"".join(parts)

    def window(self, start_s: float, end_s: float, max_bytes: int) -> tuple[bytes, int, float]:
        """The frames with ``start_s <= t_s < end_s`` as a JSON array of ``{"t_s", "frame"}``, how
        many, and the time up to which the answer is whole [s]: ``end_s``, or when the frames of
        that span are more than ``max_bytes`` [bytes] of text, the time of the first one left out
        (the frames of one time are never split; the first time's are given even if they alone
        are more, so a reader taking up from there always gets further)."""
        with self._lock:
            times = self.times
            lo = bisect.bisect_left(times, start_s)
            hi = bisect.bisect_left(times, end_s)
            if lo >= hi:
                return b"[]", 0, end_s
            first = self._ends[lo - 1] if lo else 0
            upto = end_s
            if self._ends[hi - 1] - first > max_bytes:
                cut = max(lo + 1, bisect.bisect_right(self._ends, first + max_bytes, lo, hi))
                if cut < hi and times[cut] == times[cut - 1]:  # not inside one time's frames
                    back = bisect.bisect_left(times, times[cut], lo, cut)
                    cut = back if back > lo else bisect.bisect_right(times, times[lo], lo, hi)
                if cut < hi:
                    hi, upto = cut, times[cut]
            text = self._text(first, self._ends[hi - 1] - 1)  # without the last item's comma
        return b"[" + text + b"]", hi - lo, upto
