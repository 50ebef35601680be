"""One MCAP file as the recorder writes it (``RecordingWriter`` holds one at a time): its stream,
written whole or not at all per write (``seaway.runtime.disk.AllOrNothing``), its writer
(``mcapfile.McapWriter``) and channel table, and whether another process took it away (``lost``).
``free_path`` names a file so that a recorder never overwrites one.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from seaway.runtime.disk import AllOrNothing
from seaway.runtime.private import open_private

from seaway_recorder import schemas
from seaway_recorder.mcapfile import McapWriter

log = logging.getLogger("seaway.recorder")

PROFILE = ""  # MCAP profile: none of the well-known ones (ros1, ros2) applies to JSON channels
LIBRARY = "seaway-recorder/0.1.0"


def free_path(path: Path) -> Path:
    """``path``, or ``<stem>.restart-<k>.mcap`` with the first free k: a recorder never overwrites a
    file. The name sorts right after ``path`` (and before the next rotated file), so reading a run
    folder in name order stays in time order.

    A recorder restarted into the same run folder (the launcher restarts a crashed one) must leave
    the earlier, possibly truncated, recording for ``seaway record recover``.
    """
    if not path.exists():
        return path
    for k in range(1, 100_000):
        candidate = path.with_name(f"{path.stem}.restart-{k:03d}{path.suffix}")
        if not candidate.exists():
            return candidate
    raise FileExistsError(f"no free file name next to {path}")


class OpenFile:
    """One MCAP file being written: its writer (``mcapfile``), its stream and its channel table."""

    def __init__(self, path: Path, chunk_size: int, compression: str) -> None:
        self.path = path
        # Closed in close(); only the user reads it. Unbuffered and all or nothing per write: a
        # full disk fails a write whole, where it is made (seaway.runtime.disk.AllOrNothing).
        self.stream = AllOrNothing(open_private(path, buffering=0))
        self.writer = McapWriter(self.stream, chunk_size=chunk_size, compression=compression)
        try:
            self.writer.start(profile=PROFILE, library=LIBRARY)
        except BaseException:
            self.writer.close()
            self.stream.close()
            raise
        self.schemas: dict[tuple[str, bytes], int] = {}
        self.channels: dict[str, int] = {}
        self.sequence: list[int] = [0]
        """Messages written so far per channel id (ids count from 1)."""
        self.messages = 0
        st = os.fstat(self.stream.fileno())
        self.identity = (st.st_dev, st.st_ino)
        self.moved_said = False

    def lost(self) -> str:
        """Why the file written is no longer the recording ('' if it is): deleted (or replaced by
        a rename: its bytes go nowhere once closed), or truncated under the writer (what it
        holds no longer reads). A file moved away is still written, where it went: '' (said once)."""
        fd = self.stream.fileno()
        st = os.fstat(fd)
        if st.st_nlink == 0:
            return "deleted or replaced by another process"
        # Where the OS writes next (bytes still in the stream's buffer not counted): a file shorter
        # than that was cut. Asked before the next write, which would make it as long again.
        if st.st_size < os.lseek(fd, 0, os.SEEK_CUR):
            return "truncated by another process"
        if not self.moved_said:
            try:
                here = os.stat(self.path)
                moved = (here.st_dev, here.st_ino) != self.identity
            except FileNotFoundError:
                moved = True
            if moved:
                self.moved_said = True
                log.warning("%s was moved away while recording: writing on where it went (another "
                            "file at its name is not this recording)", self.path)
        return ""

    def channel(self, spec: schemas.ChannelSpec) -> int:
        cid = self.channels.get(spec.topic)
        if cid is not None:
            return cid
        schema_id = 0
        if spec.schema_encoding:
            sk = (spec.schema_name, spec.schema_data)
            schema_id = self.schemas.get(sk, 0)
            if not schema_id:
                schema_id = self.writer.register_schema(spec.schema_name, spec.schema_encoding,
                                                        spec.schema_data)
                self.schemas[sk] = schema_id
        cid = self.writer.register_channel(spec.topic, spec.message_encoding, schema_id,
                                           dict(spec.metadata))
        self.channels[spec.topic] = cid
        self.sequence += [0] * (cid + 1 - len(self.sequence))
        return cid

    def size(self) -> int:
        return self.stream.tell()

    def close(self, metadata: tuple[str, dict[str, str]], durable: bool = False) -> None:
        """Finish the file with a last ``metadata`` record; a failed finish changes nothing.
        ``durable``: on the disk before it is closed (fdatasync; a failure is logged, the file is
        whole for the OS all the same)."""
        self.writer.finish(metadata)
        if durable:
            try:
                os.fdatasync(self.stream.fileno())
            except OSError as err:
                log.warning("could not sync %s to the disk: %s", self.path, err)
        self.stream.close()

    def abandon(self) -> None:
        """Let go of a file that could not be started: closed, and removed (it holds nothing)."""
        self.writer.close()
        self.stream.close()
        self.path.unlink(missing_ok=True)
