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
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from seaway.contract.messages import MAX_LOG_MESSAGE_CHARS, LogRecord

_RECORD = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d),(\d{3}) \S+ "
                     r"(DEBUG|INFO|WARNING|ERROR|CRITICAL) (\S+?): (.*)$")
MAX_LINE_CHARS = 8192
"""A longer line is cut (and says so): a log panel is not the place for a megabyte of text."""
assert MAX_LINE_CHARS + 60 <= MAX_LOG_MESSAGE_CHARS  # the cut line and its note fit a LogRecord


@dataclass(frozen=True)
class LogLine:
    """One line of a process's log. ``wall_ns`` [ns since the Unix epoch] is None when the line
    carries no time of its own; ``level`` is Python's name, '' if the line does not say."""

    wall_ns: int | None
    level: str
    logger: str
    message: str


def parse_line(text: str) -> LogLine:
    """One log line (local time, as ``logging``'s ``asctime`` writes it)."""
    text = text.rstrip("\r\n")
    if len(text) > MAX_LINE_CHARS:
        text = f"{text[:MAX_LINE_CHARS]} ... ({len(text) - MAX_LINE_CHARS} more characters)"
    m = _RECORD.match(text)
    if m is None:
        return LogLine(None, "", "", text)
    local = dt.datetime.strptime(m.group(1), "%Y-%m-%d %H:%M:%S").astimezone()
    wall_ns = int(local.timestamp()) * 1_000_000_000 + int(m.group(2)) * 1_000_000
    return LogLine(wall_ns, m.group(3), m.group(4), m.group(5))


def log_record(process: str, line: LogLine, now_ns: int) -> LogRecord:
    """The bus message of one line (``keys.LOG_LINE``): at its own time, else ``now_ns``."""
    return LogRecord(stamp_ns=line.wall_ns or now_ns, process=process[:64] or "?",
                     level=line.level[:16], logger=line.logger[:200], message=line.message)


class FileTail:
    """The whole lines appended to a file since the last look: a line still being written waits
    for the next look; a missing file is an empty one. The file stays open once found (one read
    a look, no open and close): the launcher only ever appends to it."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.offset = 0
        self._partial = b""
        self._file: BinaryIO | None = None

    def poll(self) -> list[bytes]:
        f = self._file
        if f is None:
            try:
                f = self._file = open(self.path, "rb")  # noqa: SIM115 - closed in close()
            except FileNotFoundError:
                return []
            f.seek(self.offset)
        data = f.read()
        if not data:
            return []
        self.offset += len(data)
        *lines, self._partial = (self._partial + data).split(b"\n")
        return [line for line in lines if line.strip()]

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
                    self._tails[name] = (Path(name).name.removesuffix(".log"), FileTail(Path(name)))

    def poll(self, now_ns: int) -> list[tuple[str, LogLine]]:
        self._scan()
        out = []
        for name, (process, tail) in self._tails.items():
            for raw in tail.poll():
                line = parse_line(raw.decode("utf-8", errors="replace"))
                last_ns, last_level = self._last.get(name, (now_ns, "INFO"))
                if line.wall_ns is None:
                    line = LogLine(last_ns, line.level or last_level, line.logger, line.message)
                self._last[name] = (line.wall_ns or now_ns, line.level or last_level)
                out.append((process, line))
        return out

    def close(self) -> None:
        for _, tail in self._tails.values():
            tail.close()
