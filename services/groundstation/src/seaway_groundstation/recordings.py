"""Recordings for the replay view: the runs folder, uploads, and a recording opened as frames.

* ``RunsFolder``: the recordings under one folder (``<run>/*.mcap`` up to two levels down, and
  ``*.mcap`` in it), named by their path relative to it. A name is refused unless it stays inside
  the folder once resolved (no ``..``, no absolute path, no symbolic link out).
* ``UploadStore``: uploaded ``.mcap`` files in a private folder, a bounded number of them, each
  checked to be MCAP and to read; named ``upload:<id>-<name>.mcap``.
* ``Library``: opens a recording with the shared reader (``seaway.recording``: series,
  crash-truncated files, duplicates), has it cut into the live stream's frames by a thread
  of its own (``timeline.py``: the first frames at once, the rest as they are cut, kept on disk)
  and keeps the ``CACHE_SIZE`` last read (a recording still being written is opened again when it
  grew; its frames are read from the state it was opened in). Nothing is ever written beside a
  recording: an unfinished one is read through the reader's repaired copy in its cache.
  Also what the page needs beside the frames (``runcontext.py``): the missions flown (the
  controller's recorded ``mission/accepted``, else the ground station's journal, the launcher's
  ``mission.json`` or the recording's attachments) in local metres, each vessel's NED origin, and
  the run's ``report/metrics.json`` when there is one.

Every refusal is a ``RecordingError`` with the HTTP status it stands for and a text naming the
recording and what is wrong.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import os
import re
import secrets
import shutil
import tempfile
import threading
from collections.abc import AsyncIterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from mcap.writer import MCAP0_MAGIC as MCAP_MAGIC  # an upload must start with it
from pydantic import BaseModel, Field
from seaway.contract import keys
from seaway.contract.messages import MissionAccepted
from seaway.runtime.disk import disk_full
from seaway.vessel.frames import GeoOrigin

from seaway_groundstation import geo, runcontext
from seaway_groundstation.geo import GeoFrameView, MissionPlanView
from seaway_groundstation.timeline import Timeline

log = logging.getLogger("seaway_groundstation.recordings")

UPLOAD_PREFIX = "upload:"
MAX_LISTED = 500
"""Recordings listed at most (the newest first)."""
MAX_SCANNED_DIRS = 5000
"""Folders looked into at most when listing (a runs folder is not a whole disk)."""
_REF_RE = re.compile(r"^[A-Za-z0-9_.][A-Za-z0-9_./-]{0,511}$")
_NAME_RE = re.compile(r"[^A-Za-z0-9_.-]+")


class RecordingError(Exception):
    """A recording that cannot be listed, opened or stored; ``status`` is the HTTP status."""

    def __init__(self, status: int, detail: str) -> None:
        super().__init__(detail)
        self.status, self.detail = status, detail


class RecordingEntry(BaseModel):
    """One recording the replay view can open."""

    id: str = Field(description="what to pass as ?id=: the path under the runs folder, or upload:...")
    name: str
    source: Literal["runs", "upload"]
    files: int = Field(description="MCAP files (a rotated series has several)")
    size_bytes: int
    modified_s: float = Field(description="newest file's modification time [s since epoch]")
    has_report: bool = Field(description="the run folder has report/metrics.json")


class RecordingList(BaseModel):
    runs_dir: str = Field(description="the folder recordings are listed from")
    recordings: list[RecordingEntry]


class RecordingDetail(RecordingEntry):
    """An opened recording: its span, vessels, frames, missions, origins and report."""

    start_ns: int = Field(description="log time of its first message [ns]")
    duration_s: float = Field(description="from its first to its last message [s]")
    message_count: int
    vessels: list[str]
    topics: dict[str, int]
    frame_count: int = Field(description="frames cut so far (every one once complete)")
    complete: bool = Field(description="every frame is cut")
    loaded_to_s: float | None = Field(description="frames before this recorded time [s] are cut "
                                                  "(null once complete)")
    rate_hz: float = Field(description="frames per second of recorded time")
    missions: list[MissionPlanView] = Field(description="missions known to have been flown, "
                                                            "in local metres (match by mission_id)")
    geo: dict[str, GeoFrameView] = Field(description="each vessel's NED origin and scale")
    report: dict[str, Any] | None = Field(description="the run's report/metrics.json, if any")
    notes: list[str] = Field(default_factory=list, description="what could not be read, and why")


def _entry_stats(files: list[Path]) -> tuple[int, float]:
    size, newest = 0, 0.0
    for f in files:
        st = f.stat()
        size, newest = size + st.st_size, max(newest, st.st_mtime)
    return size, newest


def _mcaps(folder: Path) -> list[Path]:
    return sorted(p for p in folder.glob("*.mcap")
                  if p.is_file() and not p.name.endswith(".recovered.mcap"))


class RunsFolder:
    """Recordings under ``root``; see the module's description."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)

    def _real_root(self) -> Path:
        return self.root.resolve()

    def entries(self) -> list[RecordingEntry]:
        root = self._real_root()
        if not root.is_dir():
            return []
        found: list[tuple[str, list[Path], bool]] = []
        scanned = 0
        queue: collections.deque[tuple[Path, int]] = collections.deque([(root, 0)])
        while queue and scanned < MAX_SCANNED_DIRS:
            folder, depth = queue.popleft()
            scanned += 1
            try:
                children = sorted(folder.iterdir())
            except OSError:
                continue
            if depth == 0:
                found += [(p.name, [p], False) for p in children
                          if p.suffix == ".mcap" and p.is_file() and not p.name.endswith(".recovered.mcap")]
            for child in children:
                if not child.is_dir() or child.is_symlink():
                    continue
                mcaps = _mcaps(child)
                if mcaps:
                    rel = child.relative_to(root).as_posix()
                    found.append((rel, mcaps, (child / "report" / "metrics.json").is_file()))
                elif depth < 1:
                    queue.append((child, depth + 1))
        out = []
        for rel, files, has_report in found:
            try:
                size, newest = _entry_stats(files)
            except OSError:
                continue
            out.append(RecordingEntry(id=rel, name=rel, source="runs", files=len(files), size_bytes=size,
                                      modified_s=newest, has_report=has_report))
        out.sort(key=lambda e: e.modified_s, reverse=True)
        return out[:MAX_LISTED]

    def ids_in(self, folder: Path) -> list[str]:
        """The ids of the recordings in ``folder`` (a run's: its own, and each vessel's folder's in a
        fleet run), if it is under the root; reads only, like everything here."""
        root = self._real_root()
        try:
            where = Path(folder).resolve()
            if where == root or not where.is_relative_to(root) or not where.is_dir():
                return []
            subs = sorted(p for p in where.iterdir() if p.is_dir() and not p.is_symlink())
        except OSError:
            return []
        return [d.relative_to(root).as_posix() for d in [where, *subs] if _mcaps(d)]

    def resolve(self, ref: str) -> tuple[Path, list[Path]]:
        """The folder or file ``ref`` names under the root and its MCAP files; RecordingError if the
        name is malformed (422), leaves the folder (422) or names no recording (404)."""
        if not _REF_RE.match(ref) or "\\" in ref:
            raise RecordingError(422, f"recording {ref!r}: a path under the runs folder, of letters, "
                                      "digits, '_', '.', '-' and '/'")
        parts = ref.split("/")
        if any(p in ("", ".", "..") for p in parts):
            raise RecordingError(422, f"recording {ref!r}: no empty, '.' or '..' parts")
        root = self._real_root()
        path = (root / ref).resolve()
        if not path.is_relative_to(root):
            raise RecordingError(422, f"recording {ref!r} is outside the runs folder")
        if path.is_dir():
            files = _mcaps(path)
            if not files:
                raise RecordingError(404, f"recording {ref!r}: no .mcap file in that folder")
            return path, files
        if path.is_file() and path.suffix == ".mcap":
            return path, [path]
        raise RecordingError(404, f"no recording {ref!r} in the runs folder")


class UploadStore:
    """Uploaded recordings in ``folder`` (None: a private temporary folder, removed by ``close``)."""

    def __init__(self, folder: Path | None, max_uploads: int, max_bytes: int) -> None:
        self.owned = folder is None
        self._folder = None if folder is None else Path(folder)
        self.max_uploads, self.max_bytes = max_uploads, max_bytes
        self._lock = threading.Lock()

    @property
    def folder(self) -> Path:
        """The upload folder; a private temporary one is made at the first use."""
        with self._lock:
            if self._folder is None:
                self._folder = Path(tempfile.mkdtemp(prefix="seaway-gs-uploads-"))
            return self._folder

    def _files(self) -> list[Path]:
        """Every upload held, oldest first: every ``.mcap`` here, whatever its name (``_mcaps``
        leaves out ``*.recovered.mcap``, a runs folder's repaired copies; here those are uploads
        named so, which escaped the listing and the ``max_uploads`` bound)."""
        if self._folder is None or not self._folder.is_dir():
            return []
        return sorted((p for p in self._folder.glob("*.mcap") if p.is_file()),
                      key=lambda p: p.stat().st_mtime)

    def entries(self) -> list[RecordingEntry]:
        out = []
        for p in reversed(self._files()):
            with contextlib.suppress(OSError):
                st = p.stat()
                out.append(RecordingEntry(id=UPLOAD_PREFIX + p.name, name=p.name.split("-", 1)[-1],
                                          source="upload", files=1, size_bytes=st.st_size,
                                          modified_s=st.st_mtime, has_report=False))
        return out

    def resolve(self, ref: str) -> tuple[Path, list[Path]]:
        name = ref[len(UPLOAD_PREFIX):]
        if not re.fullmatch(r"[0-9a-f]{8}-[A-Za-z0-9_.-]{1,128}\.mcap", name):
            raise RecordingError(422, f"recording {ref!r}: not an upload name (upload:<id>-<name>.mcap)")
        path = self.folder / name
        if not path.is_file():
            raise RecordingError(404, f"no uploaded recording {ref!r} (uploads are kept while the "
                                      f"ground station runs, the last {self.max_uploads})")
        return path, [path]

    async def save(self, filename: str, chunks: AsyncIterator[bytes]) -> tuple[str, Path]:
        """Write an upload from ``chunks``; (id, path). RecordingError: over ``max_bytes`` (413),
        not named .mcap or not MCAP (422), no room on the disk (507) or another write error (500):
        what was written of it is removed. The oldest uploads beyond ``max_uploads`` are removed."""
        stem = _NAME_RE.sub("_", Path(filename or "recording.mcap").name)[-100:].lstrip(".") or "recording"
        if not stem.endswith(".mcap"):
            raise RecordingError(422, f"upload {filename!r}: name an .mcap file (a Seaway recording)")
        self.folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        name = f"{secrets.token_hex(4)}-{stem}"
        path = self.folder / name
        part = path.with_suffix(".part")
        size = 0
        head = b""
        try:
            with open(part, "wb") as fh:
                async for chunk in chunks:
                    size += len(chunk)
                    if size > self.max_bytes:
                        raise RecordingError(413, f"upload {filename!r} is larger than "
                                                  f"{self.max_bytes} bytes")
                    if len(head) < len(MCAP_MAGIC):
                        head += chunk[:len(MCAP_MAGIC)]
                    fh.write(chunk)
            if not head.startswith(MCAP_MAGIC):
                raise RecordingError(422, f"upload {filename!r} is not an MCAP file (it does not start "
                                          "with the MCAP magic bytes)")
            os.replace(part, path)
        except OSError as err:  # what the disk says, as an answer naming it; not a traceback
            if disk_full(err):
                raise RecordingError(507, f"upload {filename!r}: no room for it on the ground "
                                          f"station's disk after {size} bytes ({err}); free some "
                                          "space there, or set upload_dir to a disk with room") from None
            raise RecordingError(500, f"upload {filename!r}: the ground station cannot store it: "
                                      f"{err}") from None
        finally:
            with contextlib.suppress(OSError):
                part.unlink()
        with self._lock:
            files = self._files()
            for old in files[:max(0, len(files) - self.max_uploads)]:
                remove_upload(old)
        return UPLOAD_PREFIX + name, path

    def close(self) -> None:
        if self.owned and self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)


def remove_upload(path: Path) -> None:
    with contextlib.suppress(OSError):
        path.unlink()  # a repaired copy, if it was cut, is in the reader's cache (pruned there)


@dataclass
class Loaded:
    """An opened recording: its detail and its frames (cut by a thread of their own)."""

    detail: RecordingDetail
    timeline: Timeline

    @property
    def error(self) -> str | None:
        """Why the frames stop before the recording's end (a damaged chunk), naming the recording
        by its id and the way to repair it; None while none is known."""
        err = self.timeline.error
        if err is None:
            return None
        # The reader's text: no path of this machine (as ``Library.public_text``).
        return (f"recording {self.detail.id!r} could not be read to its end: "
                f"{_ABS_PATH_RE.sub(lambda m: m.group(1), err)}")

    def current(self) -> RecordingDetail:
        """The detail with the frames cut so far (and, once all are, what could not be read)."""
        tl = self.timeline
        notes = list(self.detail.notes)
        if tl.complete and tl.undecodable:
            notes.append(f"{tl.undecodable} message(s) that do not decode were left out")
        if self.error:
            notes.append(self.error)
        return self.detail.model_copy(update={
            "frame_count": len(tl.frames), "complete": tl.complete,
            "loaded_to_s": None if tl.complete else tl.loaded_to_s, "notes": notes})


CACHE_SIZE = 4
"""Recordings kept open at once. Each holds 16 bytes per frame in memory and its frames compressed
on disk (``framestore.py``); a client replaying one more than this evicts the least recently read,
which is then cut again from its start when its client asks for more."""


class Library:
    """The runs folder and the uploads, and the ``cache_size`` recordings last read."""

    def __init__(self, runs: RunsFolder, uploads: UploadStore, rate_hz: float, stale_after_s: float,
                 cache_size: int = CACHE_SIZE) -> None:
        self.runs, self.uploads = runs, uploads
        self.rate_hz, self.stale_after_s, self.cache_size = rate_hz, stale_after_s, cache_size
        self._cache: collections.OrderedDict[tuple[Any, ...], Loaded] = collections.OrderedDict()
        self._lock = threading.Lock()
        self._opening: dict[str, threading.Lock] = {}

    def listing(self) -> RecordingList:
        return RecordingList(runs_dir=str(self.runs.root),
                             recordings=self.uploads.entries() + self.runs.entries())

    def resolve(self, ref: str) -> tuple[Path, list[Path], Literal["runs", "upload"]]:
        if ref.startswith(UPLOAD_PREFIX):
            return (*self.uploads.resolve(ref), "upload")
        return (*self.runs.resolve(ref), "runs")

    def open(self, ref: str) -> Loaded:
        """The recording ``ref``, opened (blocking: call from a worker thread); opened again when
        its files changed (a recording still being written), else the one opened before."""
        where, files, source = self.resolve(ref)
        try:
            key = (ref, *((f.name, f.stat().st_size, f.stat().st_mtime_ns) for f in files))
        except OSError as err:
            log.warning("recording %r: %s", ref, err)
            raise RecordingError(404, f"recording {ref!r}: "
                                      f"{self.public_text(str(err), ref, where, files)}") from None
        with self._lock:
            opening = self._opening.setdefault(ref, threading.Lock())
        with opening:  # one open of a recording at a time: readers at once share it
            with self._lock:
                hit = self._cache.get(key)
                if hit is not None:
                    self._cache.move_to_end(key)
                    return hit
            loaded = self._load(ref, where, files, source)
            with self._lock:
                self._cache[key] = loaded
                while len(self._cache) > self.cache_size:
                    self._cache.popitem(last=False)[1].timeline.cancel()
        return loaded

    def get(self, ref: str) -> Loaded:
        """The recording ``ref`` as last opened, even if it grew since (its frames are being read
        from that state), else opened now: a page reading its frames keeps one state of it."""
        with self._lock:
            for key in reversed(self._cache):
                if key[0] == ref:
                    # Read now: the last to be evicted. A page reads its frames here after one open,
                    # and while an LRU of opens alone evicted the one being read.
                    self._cache.move_to_end(key)
                    return self._cache[key]
        return self.open(ref)

    def public_text(self, text: str, ref: str, where: Path, files: Sequence[Path]) -> str:
        """``text`` (an error's) with no path of this machine in it: the recording's folder and
        files by their names in the API (``ref``, and a file by its path in the runs folder or its
        upload id), then any other absolute path by its last part. A client knows recordings by
        their ids; the folders behind them (a private upload folder, a repair cache) are not its
        business."""
        names: dict[str, str] = {str(where): ref}
        for f in files:
            names[str(f)] = (UPLOAD_PREFIX + f.name if ref.startswith(UPLOAD_PREFIX)
                             else _relative_name(f, self.runs._real_root()))
        for path in sorted(names, key=len, reverse=True):  # a file before the folder holding it
            text = text.replace(path, names[path])
        return _ABS_PATH_RE.sub(lambda m: m.group(1), text)

    def _unreadable(self, ref: str, where: Path, files: Sequence[Path], what: str,
                    err: Exception) -> RecordingError:
        """The 422 of a recording the reader refuses: the reader's text, logged in full here and
        answered without this machine's paths (``public_text``)."""
        log.warning("recording %r (%s) %s: %s", ref, where, what, err)
        return RecordingError(422, f"recording {ref!r} {what}: "
                                   f"{self.public_text(str(err), ref, where, files)}")

    def _load(self, ref: str, where: Path, files: list[Path], source: Literal["runs", "upload"]) -> Loaded:
        from seaway.recording import reader  # mcap is imported by the replay view alone

        try:
            readable = reader.open_paths([where]) if where.is_dir() else [reader.readable(where)]
            info = reader.read_info(readable)
        except Exception as err:  # mcap raises its own errors for damaged files; say which file
            raise self._unreadable(ref, where, files, "does not read as MCAP", err) from None
        vessels = sorted({t.split("/", 2)[1] for t in info.topics
                          if t.startswith(keys.ROOT + "/") and keys.spec_for_key(t) is not None})
        notes: list[str] = []
        origins: dict[str, GeoOrigin | None] = {}
        accepted: list[tuple[str, MissionAccepted]] = []  # (vessel, acceptance), as recorded
        for v in vessels:  # only these two: a few messages, read through the chunks' index
            try:
                dec = reader.decode_vessel(readable, v, [keys.MISSION_ACCEPTED.suffix,
                                                            keys.NAV_ORIGIN.suffix], info.summaries)
            except Exception as err:
                raise self._unreadable(ref, where, files, "does not read", err) from None
            accepted += [(v, m) for m in dec.get(keys.MISSION_ACCEPTED.suffix)
                         if isinstance(m, MissionAccepted)]
            recorded = dec.get(keys.NAV_ORIGIN.suffix)
            origins[v] = geo.geo_origin(recorded[-1]) if recorded else None  # type: ignore[arg-type]
        # A file cut short (a crash, still being written) is read through a repaired copy: say so.
        notes += [f"recording {ref!r}: {self.public_text(line, ref, where, files)}"
                  for line in reader.repaired(info)]
        scenario_name, scenario_origin = runcontext.scenario(info.attachments, notes)
        for v in vessels:
            origins[v] = origins[v] or scenario_origin
        timeline = Timeline(readable, info.summaries, info.start_ns, self.rate_hz,
                            self.stale_after_s).start()
        size, newest = _entry_stats(files)
        run_folder = where if where.is_dir() else None
        detail = RecordingDetail(
            id=ref, name=ref.removeprefix(UPLOAD_PREFIX), source=source, files=len(files),
            size_bytes=size, modified_s=newest,
            has_report=run_folder is not None and (run_folder / "report" / "metrics.json").is_file(),
            start_ns=info.start_ns, duration_s=max(0.0, (info.end_ns - info.start_ns) / 1e9),
            message_count=info.message_count, vessels=vessels, topics=info.topics,
            frame_count=0, complete=False, loaded_to_s=0.0, rate_hz=self.rate_hz,
            missions=runcontext.missions(run_folder, info.attachments, origins, scenario_name, notes,
                               accepted),
            geo={v: fv for v, o in origins.items() if (fv := geo.frame_view(o)) is not None},
            report=runcontext.report(run_folder, notes), notes=notes)
        return Loaded(detail, timeline)


_ABS_PATH_RE = re.compile(r"(?<![\w.~])(?:~|/)[^\s'\"]*/([^\s'\"/:]+)")
"""An absolute (or home-relative) path in an error's text; group 1 is its last part."""


def _relative_name(path: Path, root: Path) -> str:
    """``path`` as named under the runs folder ``root`` (its last part if it is not under it)."""
    try:
        return path.relative_to(root).as_posix()
    except ValueError:
        return path.name
