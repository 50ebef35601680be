"""The run's text logs into the recording: each process's new lines, parsed into log records.

The launcher already writes every line a process prints to ``<run>/logs/<process>.log``; the
recorder tails those files (``--logs``), as it tails the launcher's events, and writes each line as
a ``foxglove.Log`` (``writer.RecordingWriter.write_log``). Nothing in the services changes, the
text logs stay as they are, a line a crashing process printed last is still recorded, and so are
lines that are not log records (a traceback, a ``print``).

``parse_line`` reads the format every service logs in (``seaway.runtime.service.configure_logging``:
``<local time>,<ms> <service> <LEVEL> <logger>: <message>``); another line keeps the level and time
of the line before it in the same file (a traceback belongs to the error above it).
"""

from __future__ import annotations

import datetime as dt
import glob
import logging
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from seaway.contract.messages import MAX_LOG_MESSAGE_CHARS, LogRecord
from seaway.runtime.ratelog import RateLimitedLog

log = logging.getLogger("seaway.recorder")
_ratelog = RateLimitedLog(log)  # a file that cannot be opened is tried again at every look

_RECORD = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d),(\d{3}) \S+ "
                     r"(DEBUG|INFO|WARNING|ERROR|CRITICAL) (\S+?): (.*)$")
MAX_LINE_CHARS = 8192
"""A longer line is cut (and says so): a log panel is not the place for a megabyte of text."""
assert MAX_LINE_CHARS + 60 <= MAX_LOG_MESSAGE_CHARS  # the cut line and its note fit a LogRecord
MAX_LINE_BYTES = 4 * MAX_LINE_CHARS
"""Bytes of one line kept while it is read [bytes] (UTF-8 takes at most 4 a character): the rest of
a longer line (a process printing megabytes, or binary garbage, without a newline) is counted, not
held, so neither memory nor the time of a look grows with it."""
LATEST_LINE_NS = (1 << 32) * 1_000_000_000 - 1
"""The latest time a line may say it was logged at [ns since the Unix epoch]: a ``foxglove.Log``
holds its seconds in a uint32 (the year 2106). A line saying a later, earlier than 1970, or
impossible time (month 13) is kept whole, as a line without a time of its own."""
READ_BYTES = 1 << 20
"""Read at most this much of one file at a look [bytes]: a large backlog (a recorder restarted
into a run with long logs) comes over several looks, not into memory at once."""
READ_BUDGET_BYTES = 8 << 20
"""Read at most this much of all files together at a look [bytes]; the next look goes on from the
file after the last one read, so every file gets its turn."""
MAX_OPEN_FILES = 128
"""Log files kept open between looks; one found beyond them is opened, read and closed at each
look, so a log folder of thousands of files does not use up the process's file descriptors."""
CHECK_NS = 1_000_000_000
"""How often an idle file is checked for being truncated or replaced (logrotate) [ns]."""


@dataclass(frozen=True)
class LogLine:
    """One line of a process's log. ``wall_ns`` [ns since the Unix epoch] is None when the line
    carries no time of its own; ``level`` is Python's name, '' if the line does not say."""

    wall_ns: int | None
    level: str
    logger: str
    message: str


def parse_line(text: str, more_bytes: int = 0) -> LogLine:
    """One log line (local time, as ``logging``'s ``asctime`` writes it); ``more_bytes``: how many
    bytes of it were not kept (``FileTail``), said at its end with the characters cut here."""
    text = text.rstrip("\r\n")
    if len(text) > MAX_LINE_CHARS or more_bytes:
        more = [f"{len(text) - MAX_LINE_CHARS} more characters"] if len(text) > MAX_LINE_CHARS else []
        more += [f"{more_bytes} more bytes"] if more_bytes else []
        text = f"{text[:MAX_LINE_CHARS]} ... ({', '.join(more)})"
    m = _RECORD.match(text)
    if m is None:
        return LogLine(None, "", "", text)
    try:
        local = dt.datetime.strptime(m.group(1), "%Y-%m-%d %H:%M:%S").astimezone()
        wall_ns = int(local.timestamp()) * 1_000_000_000 + int(m.group(2)) * 1_000_000
    except (ValueError, OverflowError):  # month 13, year 0: not a time, so not a record's
        wall_ns = -1
    if not 0 <= wall_ns <= LATEST_LINE_NS:
        return LogLine(None, "", "", text)
    return LogLine(wall_ns, m.group(3), m.group(4), m.group(5))


def log_record(process: str, line: LogLine, now_ns: int) -> LogRecord:
    """The bus message of one line (``keys.LOG_LINE``): at its own time, else ``now_ns``."""
    return LogRecord(stamp_ns=line.wall_ns or now_ns, process=process[:64] or "?",
                     level=line.level[:16], logger=line.logger[:200], message=line.message)


class FileTail:
    """The whole lines appended to a file since the last look: a line still being written waits
    for the next look; a missing file is an empty one. The file stays open once found (one read
    a look, no open and close) unless ``keep_open`` is False. A file truncated under it (logrotate's
    copytruncate, ``: > x.log``) is read again from its start, one replaced (renamed away and made
    anew) from the new file's start, once what the old one still had is read. A file that cannot be
    opened (permissions, no file descriptor left) is said once in a while and tried again."""

    def __init__(self, path: Path, keep_open: bool = True) -> None:
        self.path = path
        self.keep_open = keep_open
        self.offset = 0
        self._partial = b""
        self._partial_cut = 0
        """Bytes of the line in progress past ``MAX_LINE_BYTES``: counted, not kept."""
        self._file: BinaryIO | None = None
        self._identity: tuple[int, int] | None = None
        """(device, inode) of the file read: another one at ``path`` is a new file."""
        self._checked_ns = 0
        self._ended: list[tuple[bytes, int]] = []
        """A line in progress that a truncation or replacement ended: returned at the next look."""
        self.read_bytes = 0
        """Bytes read in all [bytes]."""
        self.restarts = 0
        """Times the file was found truncated or replaced and read again from its start."""

    def poll(self) -> list[bytes]:
        """The new whole lines (a longer one cut to ``MAX_LINE_BYTES``)."""
        return [line for line, _ in self.poll_cut()]

    def poll_cut(self, limit: int = READ_BYTES) -> list[tuple[bytes, int]]:
        """The new whole lines read from at most ``limit`` bytes, each with the number of its bytes
        not kept (past ``MAX_LINE_BYTES``)."""
        f = self._open()
        if f is None:
            return []
        try:
            data = f.read(limit)
            if not data and self._moved(f):
                f = self._open()
                data = f.read(limit) if f is not None else b""
        finally:
            if not self.keep_open:
                self.close()
        ended, self._ended = self._ended, []
        if not data:
            return ended
        self.offset += len(data)
        self.read_bytes += len(data)
        return ended + self._lines(data)

    def _open(self) -> BinaryIO | None:
        if self._file is not None:
            return self._file
        try:
            f = open(self.path, "rb")  # noqa: SIM115 - closed in close()
        except FileNotFoundError:
            return None
        except OSError as err:  # EMFILE, EACCES: not the recording's failure; try again later
            _ratelog.warning(("open", str(self.path)), "cannot read %s (tried again): %s",
                             self.path, err)
            return None
        st = os.fstat(f.fileno())
        identity = (st.st_dev, st.st_ino)
        if self._identity is not None and identity != self._identity:
            self._restart("replaced; reading the new file from its start")
        self._identity = identity
        f.seek(self.offset)
        self._file = f
        return f

    def _moved(self, f: BinaryIO) -> bool:
        """Whether the file was truncated (then read from its start) or another file now has its
        name (then the new one is opened at the next ``_open``); at most every ``CHECK_NS``."""
        now = time.monotonic_ns()
        if self.keep_open and now - self._checked_ns < CHECK_NS:
            return False
        self._checked_ns = now
        try:
            st = os.stat(self.path)
        except OSError:
            return False  # gone for now: what was read stays read
        if (st.st_dev, st.st_ino) != self._identity:
            self.close()
            return True
        if st.st_size < self.offset:
            self._restart("truncated; reading it again from its start")
            self.offset = 0
            f.seek(0)
            return True
        return False

    def _restart(self, why: str) -> None:
        log.warning("log %s %s (%d bytes were read)", self.path, why, self.offset)
        self.restarts += 1
        self.offset = 0
        # A line cut by the truncation is still a line: it ends here, not joined to the new
        # file's first one.
        if self._partial.strip():
            self._ended.append((self._partial, self._partial_cut))
        self._partial, self._partial_cut = b"", 0

    def _lines(self, data: bytes) -> list[tuple[bytes, int]]:
        *lines, rest = data.split(b"\n")
        out: list[tuple[bytes, int]] = []
        if lines:
            first, cut = self._keep(self._partial, self._partial_cut, lines[0])
            out.append((first, cut))
            out += [(line[:MAX_LINE_BYTES], max(0, len(line) - MAX_LINE_BYTES))
                    for line in lines[1:]]
            self._partial, self._partial_cut = rest[:MAX_LINE_BYTES], max(0, len(rest) - MAX_LINE_BYTES)
        else:
            self._partial, self._partial_cut = self._keep(self._partial, self._partial_cut, rest)
        return [(line, cut) for line, cut in out if line.strip()]

    @staticmethod
    def _keep(head: bytes, cut: int, more: bytes) -> tuple[bytes, int]:
        """``head + more`` cut to ``MAX_LINE_BYTES``, with the count of bytes left out."""
        room = MAX_LINE_BYTES - len(head)
        return head + more[:max(0, room)], cut + max(0, len(more) - max(0, room))

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None


SETTLED_NS = 2_000_000_000
"""A folder whose modification time is older than this [ns] has settled: a file made in it later
changes that time. A younger one may change again within the file system's time granularity
without its time changing, so it is listed at every look."""


class LogTail:
    """Every file matching the patterns (globs, or folders meaning ``<folder>/*.log``), found as
    they appear; ``poll(now_ns)`` returns ``(process, LogLine)`` for each new line, in each file's
    order, a line without a time of its own taking the time and level of the line before it
    (``now_ns`` for the first one). The process is the file's name without ``.log``.

    A pattern's folder is listed again only when it changed (its modification time; a glob with
    wildcards in its folders at every look): the recorder looks every flush interval."""

    def __init__(self, patterns: list[str]) -> None:
        self.patterns = [str(Path(p) / "*.log") if Path(p).is_dir() else p for p in patterns]
        self._tails: dict[str, tuple[str, FileTail]] = {}
        self._last: dict[str, tuple[int, str]] = {}
        self._folders: dict[str, int] = {}
        """Per pattern whose folder has no wildcard: its folder's modification time when listed."""
        self._next = 0
        """The file the next look starts from, when the last one ran out of ``READ_BUDGET_BYTES``."""

    def _changed(self, pattern: str) -> bool:
        """Whether ``pattern``'s matches may have changed since it was last listed."""
        folder = os.path.dirname(pattern) or "."
        if any(c in folder for c in "*?["):
            return True
        try:
            mtime_ns = os.stat(folder).st_mtime_ns
        except OSError:
            return True
        if self._folders.get(pattern) == mtime_ns and time.time_ns() - mtime_ns > SETTLED_NS:
            return False
        self._folders[pattern] = mtime_ns
        return True

    def _scan(self) -> None:
        for pattern in self.patterns:
            if not self._changed(pattern):
                continue
            for name in sorted(glob.glob(pattern)):
                if name not in self._tails and name.endswith(".log"):
                    tail = FileTail(Path(name), keep_open=len(self._tails) < MAX_OPEN_FILES)
                    self._tails[name] = (Path(name).name.removesuffix(".log"), tail)

    def poll(self, now_ns: int) -> list[tuple[str, LogLine]]:
        self._scan()
        out = []
        names = list(self._tails)
        budget = READ_BUDGET_BYTES
        start = self._next % len(names) if names else 0
        for k, name in enumerate(names[start:] + names[:start]):
            if budget <= 0:
                self._next = start + k  # the next look starts here
                break
            process, tail = self._tails[name]
            before = tail.read_bytes
            lines = tail.poll_cut(min(READ_BYTES, budget))
            budget -= tail.read_bytes - before
            for raw, cut in lines:
                line = parse_line(raw.decode("utf-8", errors="replace"), cut)
                last_ns, last_level = self._last.get(name, (now_ns, "INFO"))
                if line.wall_ns is None:
                    line = LogLine(last_ns, line.level or last_level, line.logger, line.message)
                self._last[name] = (line.wall_ns or now_ns, line.level or last_level)
                out.append((process, line))
        return out

    def close(self) -> None:
        for _, tail in self._tails.values():
            tail.close()
