"""The ground station's record of what the operator asked, in the run folder (a JSON line each).

``<run_dir>/groundstation/requests.jsonl``: every request that moves or changes a vessel, with the
vessel's answer::

    {"time_ns": ..., "vessel": "vessel1", "request": "mission/set", "outcome": "accepted",
     "reason": "...", "message": {MissionRequest ...}}

It is the operator's audit trail beside the recording (requests are queries, which the recorder
does not see), and the replay view reads the missions sent from here back from it to draw them.
Writing never fails a request: an error is logged once and the journal goes quiet.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from seaway.contract import keys
from seaway.contract.messages import MessageError, MissionRequest
from seaway.tools.launch.address import FOLDER

log = logging.getLogger("seaway_groundstation.journal")

REQUESTS = "requests.jsonl"


def requests_path(run_dir: Path) -> Path:
    return run_dir / FOLDER / REQUESTS


class RequestJournal:
    """Appends one JSON line per request to ``requests_path(run_dir)`` (None: records nothing)."""

    def __init__(self, run_dir: Path | None) -> None:
        self.path = None if run_dir is None else requests_path(run_dir)
        self._lock = threading.Lock()
        self._failed = False

    def record(self, vessel: str, request: str, outcome: str, reason: str, message: dict[str, Any]) -> None:
        if self.path is None or self._failed:
            return
        line = json.dumps({"time_ns": time.time_ns(), "vessel": vessel, "request": request,
                           "outcome": outcome, "reason": reason, "message": message})
        try:
            with self._lock:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                with open(self.path, "a", encoding="utf-8") as fh:
                    fh.write(line + "\n")
        except OSError as err:
            self._failed = True
            log.error("cannot write the requests journal %s (%s); no further requests are recorded",
                      self.path, err)


def accepted_missions(run_dir: Path, max_bytes: int = 16 << 20) -> Iterator[tuple[str, MissionRequest]]:
    """(vessel, mission) of every accepted ``mission/set`` in a run folder's journal, in order.
    Lines that do not read are skipped (a journal cut by a crash ends mid-line)."""
    path = requests_path(run_dir)
    try:
        if not path.is_file() or path.stat().st_size > max_bytes:
            return
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return
    for line in text.splitlines():
        try:
            entry = json.loads(line)
            if entry.get("request") != keys.MISSION_SET.suffix or entry.get("outcome") != "accepted":
                continue
            yield str(entry["vessel"]), MissionRequest.model_validate(entry["message"])
        except (ValueError, KeyError, TypeError, AttributeError, MessageError):
            continue
