"""What the ground station's endpoints share: ``GroundStation`` (the bus, the fleet, the stream hub,
the limits, the journal, the recordings, the last missions) and how a vessel's answer becomes an
HTTP status (``STATUS_OF_OUTCOME``)."""

import time
from pathlib import Path
from typing import Any

from fastapi import HTTPException
from fastapi.responses import JSONResponse
from seaway.contract import keys
from seaway.contract.config import ConfigError, deploy_path, read_document
from seaway.contract.messages import Message, MissionRequest
from seaway.runtime.bus import Bus
from starlette.concurrency import run_in_threadpool

from seaway_groundstation import bodies, guard
from seaway_groundstation.fleet import Fleet
from seaway_groundstation.gateway import BusLink, UnsendableError, ask
from seaway_groundstation.journal import RequestJournal
from seaway_groundstation.limits import RateLimiter
from seaway_groundstation.recordings import Library, RunsFolder, UploadStore
from seaway_groundstation.settings import Settings
from seaway_groundstation.stream import StreamHub
from seaway_groundstation.views import CommandNote, CommandReply, MissionReply

STATUS_OF_OUTCOME = {"accepted": 200, "refused": 409, "no_reply": 504, "error_reply": 502}


class GroundStation:
    """What the endpoints share: the bus, the fleet, the stream hub, the limits, the last missions."""

    def __init__(self, bus: Bus, settings: Settings) -> None:
        self.bus, self.settings = bus, settings
        self.fleet = Fleet(settings.stale_after_s, settings.default_origin, settings.max_vessels,
                           settings.forget_after_s)
        self.hub = StreamHub(self.fleet, settings.stream_rate_hz, settings.max_stream_clients,
                             settings.clock, settings.stream_send_timeout_s)
        self.link = BusLink(bus, self.fleet, settings.clock, self.hub.notify)
        self.limiter = RateLimiter(settings.rate_limit_per_s, settings.rate_limit_burst)
        self.journal = RequestJournal(settings.run_dir)
        self.library = Library(RunsFolder(settings.runs_dir),
                               UploadStore(settings.upload_dir, settings.max_uploads,
                                           settings.max_upload_bytes),
                               settings.replay_rate_hz, settings.stale_after_s)
        self._launcher_mission: tuple[int, MissionRequest | None] | None = None

    def learn_mission(self, vessel: str) -> None:
        """If the vessel flies a mission this ground station did not send, look for it in the run
        folder's ``mission.json`` (the launcher's), so the map can draw it."""
        mission_id = self.fleet.active_mission_id(vessel)
        if mission_id is None or self.fleet.mission(vessel, mission_id) is not None:
            return
        req = self._read_launcher_mission()
        if req is not None and req.mission_id == mission_id:
            self.fleet.record_mission(vessel, req, source="launcher")

    def _read_launcher_mission(self) -> MissionRequest | None:
        run_dir = self.settings.run_dir
        path = None if run_dir is None else Path(run_dir) / "mission.json"
        try:
            mtime = path.stat().st_mtime_ns if path is not None else None
        except OSError:
            mtime = None
        if path is None or mtime is None:
            return None
        if self._launcher_mission is None or self._launcher_mission[0] != mtime:
            try:
                self._launcher_mission = (mtime, MissionRequest.decode(path.read_bytes()))
            except (OSError, ValueError):
                self._launcher_mission = (mtime, None)
        return self._launcher_mission[1]

    def known(self, vessel: str) -> None:
        if not self.fleet.knows(vessel):
            seen = ", ".join(self.fleet.vessels()) or "none yet"
            raise HTTPException(404, f"vessel {vessel!r} has not been seen (no health token or "
                                     f"message from it); vessels seen: {seen}")

    async def send(self, spec: keys.KeySpec, msg: Message, vessel: str) -> CommandReply:
        self.known(vessel)
        try:
            reply = await run_in_threadpool(ask, self.bus, spec, msg, vessel,
                                            self.settings.request_timeout_s)
        except UnsendableError as err:  # nothing was sent: the body's fault, not the vessel's
            raise HTTPException(422, str(err)) from None
        await run_in_threadpool(self.journal.record, vessel, spec.suffix, reply.outcome, reply.reason,
                                msg.model_dump(mode="json"))
        self.fleet.on_command(vessel, CommandNote(
            request=spec.suffix, what=bodies.command_words(msg), outcome=reply.outcome,
            reason=reply.reason, client=guard.commander.get(), stamp_ns=time.time_ns()),
            self.settings.clock())
        self.hub.notify(vessel)
        return reply

    async def send_mission(self, vessel: str, req: MissionRequest,
                           skipped: tuple[str, ...] = ()) -> JSONResponse:
        reply = await self.send(keys.MISSION_SET, req, vessel)
        if reply.accepted:
            self.fleet.record_mission(vessel, req)
        out = MissionReply(**reply.model_dump(), mission=req, skipped=list(skipped))
        return JSONResponse(out.model_dump(mode="json"), status_code=STATUS_OF_OUTCOME[reply.outcome])

    def scenario_document(self, name: str) -> dict[str, Any]:
        folder = self.settings.scenario_dir
        try:
            path = (folder / f"{name}.toml") if folder else deploy_path("scenarios", f"{name}.toml")
            return read_document(path)
        except ConfigError as err:
            raise HTTPException(404, f"no scenario {name!r}: {err}") from None


__all__ = ["STATUS_OF_OUTCOME", "GroundStation"]
