"""The ground station's HTTP and WebSocket API: ``create_app(bus, settings)``.

Every request that moves or changes a vessel becomes the bus request it stands for and answers
with the vessel's ``Reply``: 200 accepted, 409 refused (with the reason), 504 nobody answered, 502
the transport answered with an error; 404 for a vessel never seen, 422 for an invalid body, 401
without the operator token, 403 with a wrong one, 413 for a body over the bound, 429 past the
command rate. Reading (the fleet, exports, the stream) is open.

The WebSocket ``/api/stream?vessel=NAME`` (repeatable; none: every vessel) sends JSON frames, one
per vessel with news, at most ``stream_rate_hz`` per client::

    {"vessel": "vessel1", "services": ["controller", ...], "stale_after_s": 2.0,
     "updates": {"state": {"age_s": 0.01, "stale": false, "message": {StateEstimate}},
                 "solve": {... SolveRecord, with predicted_x_m/predicted_y_m ...},
                 "mission": {... MissionStatus ...}, "vehicle": {... VehicleStatus ...},
                 "origin": {... NavOrigin ...}, "thrust": {... ThrustCommand ...},
                 "energy": {... EnergyBudget: energy used, to finish, to home, battery, margin,
                            point of no return (local NED), decision ...},
                 "area": {... ActiveArea: keep-in, keep-outs, rally points (local NED) ...},
                 "battery": {... BatteryState ...}, "gnss": {... GnssFix ...},
                 "command": {... CommandNote: the latest request this ground station relayed to the
                             vessel, its answer and the sending page's X-Seaway-Client id ...}}}

with only the kinds that changed since the client's last frame (the latest of each, never a
backlog; ``stream.py`` says how a slow client is kept from slowing the others).
"""

import asyncio
import contextlib
import importlib.resources
import json
import time
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, FastAPI, HTTPException, Query, Request
from fastapi import Path as PathParam
from fastapi.exceptions import RequestValidationError
from fastapi.middleware.gzip import GZipMiddleware
from fastapi.responses import FileResponse, JSONResponse, Response
from fastapi.staticfiles import StaticFiles
from pydantic import BaseModel, Field, ValidationError
from seaway import mission_files as plans
from seaway.contract import keys
from seaway.contract.config import ConfigError, deploy_path, read_document
from seaway.contract.messages import (
    ArmRequest,
    Message,
    MessageError,
    MissionCommand,
    MissionRequest,
    ModeRequest,
    ScenarioRequest,
)
from seaway.runtime.bus import Bus
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import UploadFile
from starlette.websockets import WebSocket

from seaway_groundstation import bodies, errors, geo, guard, mission_checks, tiles
from seaway_groundstation.fleet import Fleet
from seaway_groundstation.gateway import BusLink, ask
from seaway_groundstation.journal import RequestJournal
from seaway_groundstation.limits import BodyLimit, RateLimiter
from seaway_groundstation.progress import MetricsView
from seaway_groundstation.recordings import (
    Library,
    RecordingDetail,
    RecordingEntry,
    RecordingError,
    RecordingList,
    RunsFolder,
    UploadStore,
)
from seaway_groundstation.settings import Settings
from seaway_groundstation.stream import StreamHub
from seaway_groundstation.views import (
    CommandNote,
    CommandReply,
    ErrorBody,
    FleetView,
    MissionReply,
    ParsedMission,
    UnprocessableBody,
    VesselView,
)

API_VERSION = "1"
STATUS_OF_OUTCOME = {"accepted": 200, "refused": 409, "no_reply": 504, "error_reply": 502}
VesselName = Annotated[str, PathParam(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$", examples=["vessel1"],
                                      description="vessel name (the key namespace seaway/<vessel>/...)")]
TAGS = [
    {"name": "fleet", "description": "The vessels seen (health tokens) and their latest messages."},
    {"name": "mission", "description": "Send, import, export, start, pause, resume and abort missions."},
    {"name": "vehicle", "description": "Arm, disarm and change the autopilot's mode."},
    {"name": "sim", "description": "Load or restart the simulated scenario (simulated vessels only)."},
    {"name": "replay", "description": "Recordings under the runs folder (or uploaded) as the live "
                                      "stream's frames, for the page's replay view."},
    {"name": "page", "description": "What the page needs to know about this ground station."},
]
STATIC = importlib.resources.files("seaway_groundstation") / "static"
"""The page: plain HTML, CSS and ES modules shipped in the package (no build step, no CDN)."""
UPLOAD_PATH = "/api/recordings/upload"
FRAMES_WAIT_S = 2.0
"""How long a frames request waits for frames not yet cut [s] before it answers with fewer."""
RecordingId = Annotated[str, Query(
    min_length=1, max_length=600, examples=["20260101-120000-sim-lake-cc-empc"],
    description="a recording's id from GET /api/recordings: its path under the runs folder, or upload:...")]


def _errors(description: str) -> dict[str, Any]:
    return {"model": ErrorBody, "description": description}


def _unprocessable(description: str) -> dict[str, Any]:
    return {"model": UnprocessableBody, "description": description}


def _command_responses(reply_model: type[BaseModel]) -> dict[int | str, dict[str, Any]]:
    return {
        401: _errors("no operator token (Authorization: Bearer <token>)"),
        403: _errors("wrong operator token"),
        404: _errors("vessel never seen"),
        409: {"model": reply_model, "description": "refused by the vessel; the reason says why"},
        413: _errors("request body over the bound"),
        429: _errors("too many command requests from this identity: the operator, or this "
                             "address without the token (see Retry-After)"),
        502: {"model": reply_model, "description": "the transport answered with an error"},
        504: {"model": reply_model, "description": "nobody answered in time (service not running?)"},
    }


class GroundStation:
    """What the endpoints share: the bus, the fleet, the stream hub, the limits, the last missions."""

    def __init__(self, bus: Bus, settings: Settings) -> None:
        self.bus, self.settings = bus, settings
        self.fleet = Fleet(settings.stale_after_s, settings.default_origin)
        self.hub = StreamHub(self.fleet, settings.stream_rate_hz, settings.max_stream_clients,
                             settings.clock)
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
        reply = await run_in_threadpool(ask, self.bus, spec, msg, vessel, self.settings.request_timeout_s)
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


def _reply(reply: CommandReply) -> JSONResponse:
    return JSONResponse(reply.model_dump(mode="json"), status_code=STATUS_OF_OUTCOME[reply.outcome])


def create_app(bus_like: Bus, settings: Settings | None = None,
               on_ready: Callable[[], None] | None = None) -> FastAPI:
    """The ground station's application over ``bus_like`` (a Zenoh or in-memory ``Bus``).

    At startup it subscribes to every vessel's messages and health and then calls ``on_ready``
    (the service declares its health token there); at shutdown it withdraws the subscriptions.
    The bus itself belongs to the caller.
    """
    settings = settings or Settings()
    gs = GroundStation(bus_like, settings)

    @contextlib.asynccontextmanager
    async def lifespan(_app: FastAPI) -> AsyncIterator[None]:
        gs.hub.bind(asyncio.get_running_loop())
        gs.link.attach()
        if on_ready is not None:
            await run_in_threadpool(on_ready)
        try:
            yield
        finally:
            gs.link.close()
            gs.hub.bind(None)
            gs.library.uploads.close()

    app = FastAPI(title="Seaway ground station", version=API_VERSION, lifespan=lifespan,
                  description=__doc__, openapi_tags=TAGS, docs_url=None, redoc_url=None,
                  responses={400: _errors("a malformed request: a Content-Length that is not a number"),
                             422: {"model": UnprocessableBody, "description": "an invalid request: "
                                   "the fields at fault (each input echoed cut short), a body that "
                                   "is not UTF-8 JSON, or what in the content is wrong"}})
    app.state.groundstation = gs
    app.add_exception_handler(RequestValidationError, errors.unprocessable_response)
    # Outermost first on the way in: the body bound before anything reads a body; replay frames
    # (megabytes of JSON for a long run) go out compressed.
    app.add_middleware(GZipMiddleware, minimum_size=4096)
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes,
                       streamed={UPLOAD_PATH: settings.max_upload_bytes})
    command = [Depends(guard.command_dependency(settings, gs.limiter))]
    app.include_router(_read_router(gs), prefix="/api")
    app.include_router(_mission_router(gs, command), prefix="/api")
    app.include_router(_vehicle_router(gs, command), prefix="/api")
    app.include_router(_replay_router(gs, command), prefix="/api")

    @app.websocket("/api/stream")
    async def stream(websocket: WebSocket, vessel: Annotated[list[str] | None, Query()] = None) -> None:
        wanted = None
        if vessel:
            try:
                wanted = frozenset(keys.check_vessel(v) for v in vessel)
            except keys.KeyNameError as err:
                await websocket.close(code=1008, reason=str(err)[:120])
                return
        await gs.hub.serve(websocket, wanted)

    with importlib.resources.as_file(STATIC) as static_dir:
        index_html = Path(static_dir) / "index.html"
        app.mount("/static", StaticFiles(directory=static_dir), name="static")

    @app.get("/", include_in_schema=False)
    async def index() -> FileResponse:
        # no-cache: a ground station updated in place serves its new page at the next load
        return FileResponse(index_html, headers={"Cache-Control": "no-cache"})

    if settings.tiles is not None and tiles.is_mbtiles(settings.tiles):
        mbtiles = tiles.MBTiles(settings.tiles)

        @app.get("/tiles/{z}/{x}/{y}", include_in_schema=False)
        async def mb_tile(z: Annotated[int, PathParam(ge=0, le=tiles.MAX_ZOOM)],
                          x: Annotated[int, PathParam(ge=0)], y: Annotated[int, PathParam(ge=0)]) -> Response:
            data = await run_in_threadpool(mbtiles.tile, z, x, y)
            if data is None:
                raise HTTPException(404, f"no tile {z}/{x}/{y} in {mbtiles.path.name}")
            return Response(data, media_type=mbtiles.media_type,
                            headers={"Cache-Control": "max-age=3600"})
    elif settings.tiles is not None and not settings.tiles.startswith(("http://", "https://")):
        tiles_dir = Path(settings.tiles).resolve()

        @app.get("/tiles/{z}/{x}/{y}.png", include_in_schema=False)
        async def tile(z: Annotated[int, PathParam(ge=0, le=24)], x: Annotated[int, PathParam(ge=0)],
                       y: Annotated[int, PathParam(ge=0)]) -> FileResponse:
            path = tiles_dir / str(z) / str(x) / f"{y}.png"
            if x >= 2 ** z or y >= 2 ** z or not path.is_file():
                raise HTTPException(404, f"no tile {z}/{x}/{y} in the tiles folder")
            return FileResponse(path, media_type="image/png")

    return app


class PageConfig(BaseModel):
    """What the page needs to know about this ground station."""

    api_version: str
    stale_after_s: float = Field(description="age beyond which a figure is shown as stale [s]")
    stream_rate_hz: float
    tiles_url: str | None = Field(description="map tile URL template with {z}/{x}/{y}; None: no tiles")
    controllers: list[str]
    max_upload_bytes: int
    runs_dir: str
    live_recordings: list[str] = Field(
        default_factory=list, description="ids of the live run's recordings (its folder's, and its "
                                          "vessels' folders' in a fleet): the plots' history")


def _read_router(gs: GroundStation) -> APIRouter:
    r = APIRouter(tags=["fleet"])

    @r.get("/config", response_model=PageConfig, tags=["page"], summary="The page's settings")
    async def config() -> PageConfig:
        from seaway.contract.messages import CONTROLLER_NAMES

        s = gs.settings
        return PageConfig(api_version=API_VERSION, stale_after_s=s.stale_after_s,
                          stream_rate_hz=s.stream_rate_hz, tiles_url=s.tiles_url,
                          controllers=list(CONTROLLER_NAMES), max_upload_bytes=s.max_upload_bytes,
                          runs_dir=str(s.runs_dir),
                          live_recordings=[] if s.run_dir is None else
                          await run_in_threadpool(gs.library.runs.ids_in, Path(s.run_dir)))

    @r.get("/vessels", response_model=FleetView, summary="Every vessel seen, with its latest messages")
    async def vessels() -> FleetView:
        for name in gs.fleet.vessels():
            gs.learn_mission(name)
        return gs.fleet.views(gs.settings.clock())

    @r.get("/vessels/{vessel}", response_model=VesselView, summary="One vessel",
           responses={404: _errors("vessel never seen")})
    async def one_vessel(vessel: VesselName) -> VesselView:
        gs.known(vessel)
        gs.learn_mission(vessel)
        view = gs.fleet.view(vessel, gs.settings.clock())
        assert view is not None  # known vessels have a view
        return view

    @r.get("/vessels/{vessel}/metrics", response_model=MetricsView | None,
           summary="The paper's metrics of the current mission so far",
           responses={404: _errors("vessel never seen"),
                      409: _errors("the samples heard cannot make metrics (a span over "
                                   "seaway.vessel.metrics.MAX_GRID_SAMPLES)")})
    async def metrics(vessel: VesselName) -> MetricsView | None:
        """Travel time, energy and average cross-track error as ``seaway report`` defines them,
        from the states and thrust commands heard since the mission became active. ``null`` when
        the vessel flies no mission whose waypoints this ground station knows."""
        gs.known(vessel)
        gs.learn_mission(vessel)
        try:
            return await run_in_threadpool(gs.fleet.metrics, vessel, gs.settings.alpha_w_per_n2,
                                           gs.settings.control_period_s)
        except ValueError as err:
            raise HTTPException(409, f"no metrics for {vessel!r}: {err}") from None

    return r


_IMPORT_BODY = {
    "required": True,
    "content": {
        "multipart/form-data": {"schema": {
            "type": "object", "required": ["file"],
            "properties": {"file": {"type": "string", "format": "binary",
                                    "description": "a QGroundControl .plan or a GeoJSON file"},
                           **bodies.ImportParams.model_json_schema()["properties"]}}},
        "application/json": {"schema": bodies.ImportBody.model_json_schema()},
    },
}


def _mission_router(gs: GroundStation, command: list[Any]) -> APIRouter:
    r = APIRouter(tags=["mission"])

    @r.post("/vessels/{vessel}/mission", response_model=MissionReply, dependencies=command,
            responses=_command_responses(MissionReply), summary="Send a mission (it starts at once)")
    async def send_mission(vessel: VesselName, body: bodies.MissionBody) -> JSONResponse:
        """Waypoints in local metres or latitude/longitude; the controller validates the mission
        again and starts it from P_0 (``mission/set``)."""
        try:
            req = bodies.mission_from_body(body, time.time_ns())
        except bodies.MissionBuildError as err:
            raise HTTPException(422, str(err)) from None
        return await gs.send_mission(vessel, req)

    @r.post("/vessels/{vessel}/mission/import", response_model=MissionReply, dependencies=command,
            responses={**_command_responses(MissionReply), 415: _errors("neither multipart nor JSON")},
            openapi_extra={"requestBody": _IMPORT_BODY},
            summary="Import a .plan or GeoJSON file as a mission and send it")
    async def import_mission(vessel: VesselName, request: Request) -> JSONResponse:
        """A file upload (``multipart/form-data``: ``file`` plus the parameters as fields) or a JSON
        body (``document`` plus the parameters). Parameters not given come from the file."""
        gs.known(vessel)
        params, doc = await _read_import(request, gs.settings.max_body_bytes)
        try:
            path = plans.parse_document(doc, skip_unsupported=params.skip_unsupported,
                                        max_waypoints=gs.settings.max_waypoints)
            req = bodies.mission_from_import(path, params, time.time_ns())
        except (plans.PlanError, bodies.MissionBuildError) as err:
            raise HTTPException(422, str(err)) from None
        return await gs.send_mission(vessel, req, path.skipped)

    @r.post("/missions/check",
            responses={404: _errors("the vessel named is not known"),
                       413: _errors("request body over the bound"),
                       422: _unprocessable("not a valid mission body")},
            summary="Check a mission before sending it (nothing is sent)")
    async def check_mission(body: mission_checks.MissionCheckBody,
                            vessel: Annotated[str | None, Query(
                                pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$",
                                description="check against this vessel's live state and area "
                                            "(none: at the desk, the run's vessel model)")] = None
                            ) -> JSONResponse:
        """The controller's own check (``seaway mission check``): path length, predicted time and
        energy, battery after, reserve, energy home from the last waypoint, the operating area's
        verdict; ``{"verdict": "ok"|"refused", "reasons": [...], ...}``."""
        if vessel is not None:
            gs.known(vessel)
        try:
            req = bodies.mission_from_body(body, time.time_ns())
        except bodies.MissionBuildError as err:
            raise HTTPException(422, str(err)) from None
        out = mission_checks.live_check(req, gs.fleet, vessel, gs.settings.clock(),
                                        gs.settings.model_vessel_file, body.battery_j)
        return JSONResponse(out)

    @r.post("/missions/parse", response_model=ParsedMission,
            responses={404: _errors("the vessel named is not known"),
                       413: _errors("request body over the bound"),
                       422: _unprocessable("not a mission file")},
            summary="Read a .plan or GeoJSON document into waypoints, sending nothing")
    async def parse_mission(body: bodies.ParseBody,
                            vessel: Annotated[str | None, Query(
                                pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$",
                                description="also give the waypoints in this vessel's local metres")] = None
                            ) -> ParsedMission:
        if vessel is not None:
            gs.known(vessel)
        try:
            path = plans.parse_document(body.document, skip_unsupported=body.skip_unsupported,
                                        max_waypoints=gs.settings.max_waypoints)
        except plans.PlanError as err:
            raise HTTPException(422, str(err)) from None
        metres = None if vessel is None else geo.points_m(path.points_deg, gs.fleet.geo_origin(vessel))
        area = None if path.area is None else path.area.model_dump(mode="json", exclude_none=True)
        return ParsedMission(source=path.source, skipped=list(path.skipped), hints=path.hints, area=area,
                             speeds_mps=list(path.speeds_mps),
                             waypoints=[{"lat_deg": a, "lon_deg": b} for a, b in path.points_deg],
                             waypoints_m=None if metres is None else [{"x_m": x, "y_m": y}
                                                                      for x, y in metres])

    @r.post("/missions/export", summary="Write a mission (not sent) as a .plan or GeoJSON file",
            responses={200: {"content": {"application/json": {}, "application/geo+json": {}},
                             "description": "a QGroundControl .plan or a GeoJSON Feature"},
                       404: _errors("vessel never seen"),
                       409: _errors("waypoints in metres and no NED origin known"),
                       413: _errors("request body over the bound")})
    async def export_draft(body: bodies.MissionBody,
                           vessel: Annotated[str | None, Query(
                               pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$",
                               description="whose NED origin converts waypoints in metres")] = None,
                           format: Annotated[Literal["plan", "geojson"], Query()] = "plan") -> Response:
        """The page's mission being edited, as a file, sending nothing. Metres go through the
        vessel's origin (else the run's)."""
        if vessel is not None:
            gs.known(vessel)
        origin = gs.fleet.geo_origin(vessel) if vessel is not None else gs.settings.default_origin
        try:
            req = bodies.mission_from_body(body, time.time_ns())
        except bodies.MissionBuildError as err:
            raise HTTPException(422, str(err)) from None
        return _mission_file(req, origin, vessel or "mission", format)

    @r.get("/vessels/{vessel}/mission/export", summary="The last mission sent, as a file",
           responses={200: {"content": {"application/json": {}, "application/geo+json": {}},
                            "description": "a QGroundControl .plan or a GeoJSON Feature"},
                      404: _errors("vessel never seen, or no mission sent to it from here"),
                      409: _errors("waypoints in metres and no NED origin known")})
    async def export_mission(vessel: VesselName,
                             format: Annotated[Literal["plan", "geojson"], Query()] = "plan") -> Response:
        gs.known(vessel)
        req = gs.fleet.last_mission(vessel)
        if req is None:
            raise HTTPException(404, f"no mission has been sent to {vessel} from this ground station")
        return _mission_file(req, gs.fleet.geo_origin(vessel), vessel, format)

    @r.post("/vessels/{vessel}/mission/start", response_model=MissionReply, dependencies=command,
            responses=_command_responses(MissionReply),
            summary="Start the last mission sent from here again, from P_0")
    async def start_mission(vessel: VesselName) -> JSONResponse:
        gs.known(vessel)
        last = gs.fleet.last_mission(vessel)
        if last is None:
            raise HTTPException(404, f"no mission has been sent to {vessel} from this ground station; "
                                     "send one (POST .../mission), which starts it")
        return await gs.send_mission(vessel, last.model_copy(update={"stamp_ns": time.time_ns()}))

    def mission_command(name: Literal["pause", "resume", "abort"]) -> None:
        @r.post(f"/vessels/{{vessel}}/mission/{name}", response_model=CommandReply,
                dependencies=command, responses=_command_responses(CommandReply),
                summary=f"{name.capitalize()} the active mission", name=f"mission_{name}")
        async def handler(vessel: VesselName) -> JSONResponse:
            msg = MissionCommand.make(stamp_ns=time.time_ns(), command=name)
            return _reply(await gs.send(keys.MISSION_COMMAND, msg, vessel))

    for name in ("pause", "resume", "abort"):
        mission_command(name)  # type: ignore[arg-type]
    return r


def _mission_file(req: MissionRequest, origin: Any, vessel: str,
                  format: Literal["plan", "geojson"]) -> Response:
    """``req`` as a .plan or GeoJSON download (metres through ``origin``); 409 without one."""
    try:
        points = bodies.mission_points_deg(req.waypoints, origin)
    except bodies.ExportError as err:
        raise HTTPException(409, str(err)) from None
    if format == "plan":
        doc, media, ext = plans.to_plan(points, coa_radius_m=req.coa_radius_m,
                                        cruise_speed_mps=req.speed_hint_mps), "application/json", "plan"
    else:
        doc, media, ext = plans.to_geojson(points, bodies.mission_properties(req)), \
            "application/geo+json", "geojson"
    name = f"{vessel}-{req.mission_id or 'mission'}".replace('"', "")
    return Response(json.dumps(doc, indent=2), media_type=media,
                    headers={"Content-Disposition": f'attachment; filename="{name}.{ext}"'})


async def _read_import(request: Request, max_bytes: int) -> tuple[bodies.ImportParams, Any]:
    """The import's parameters and parsed document, from a multipart upload or a JSON body."""
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if ctype == "multipart/form-data":
        async with request.form(max_files=1, max_fields=16, max_part_size=max_bytes) as form:
            upload = form.get("file")
            if not isinstance(upload, UploadFile):
                raise HTTPException(422, "a multipart import needs the mission file in a 'file' part")
            data = await upload.read()
            fields = {k: v for k, v in form.items() if k != "file"}
            filename = upload.filename or "file"
        try:
            params = bodies.ImportParams.model_validate(fields)
        except ValidationError as err:
            raise errors.validation_error(err) from None
        try:
            doc = plans.load_json(data, f"uploaded {filename}")
        except plans.PlanError as err:
            raise HTTPException(422, str(err)) from None
        return params, doc
    if ctype in ("application/json", "application/geo+json") or ctype.endswith("+json"):
        try:
            raw = plans.load_json(await request.body(), "request body")
        except plans.PlanError as err:
            raise HTTPException(422, str(err)) from None
        try:
            body = bodies.ImportBody.model_validate(raw, strict=True)
        except ValidationError as err:
            raise errors.validation_error(err) from None
        return body, body.document
    raise HTTPException(415, f"send the file as multipart/form-data or a JSON body, not {ctype or 'nothing'}")


def _vehicle_router(gs: GroundStation, command: list[Any]) -> APIRouter:
    r = APIRouter(tags=["vehicle"])

    @r.post("/vessels/{vessel}/arm", response_model=CommandReply, dependencies=command,
            responses=_command_responses(CommandReply), summary="Arm the vehicle")
    async def arm(vessel: VesselName, body: bodies.ArmBody | None = None) -> JSONResponse:
        msg = ArmRequest.make(stamp_ns=time.time_ns(), arm=True, force=bool(body and body.force))
        return _reply(await gs.send(keys.VEHICLE_ARM, msg, vessel))

    @r.post("/vessels/{vessel}/disarm", response_model=CommandReply, dependencies=command,
            responses=_command_responses(CommandReply), summary="Disarm the vehicle")
    async def disarm(vessel: VesselName, body: bodies.ArmBody | None = None) -> JSONResponse:
        msg = ArmRequest.make(stamp_ns=time.time_ns(), arm=False, force=bool(body and body.force))
        return _reply(await gs.send(keys.VEHICLE_ARM, msg, vessel))

    @r.post("/vessels/{vessel}/home", response_model=CommandReply, dependencies=command,
            responses=_command_responses(CommandReply), summary="Set the vessel's home")
    async def set_home(vessel: VesselName, body: bodies.HomeBody) -> JSONResponse:
        """Where a return goes, and the home of every mission that gives none (until set: where
        the vessel was armed); refused by the controller outside the operating area."""
        try:
            msg = body.to_request(time.time_ns())
        except bodies.MissionBuildError as err:
            raise HTTPException(422, str(err)) from None
        return _reply(await gs.send(keys.MISSION_HOME, msg, vessel))

    @r.post("/vessels/{vessel}/mode", response_model=CommandReply, dependencies=command,
            responses=_command_responses(CommandReply), summary="Change the autopilot mode")
    async def mode(vessel: VesselName, body: bodies.ModeBody) -> JSONResponse:
        msg = ModeRequest.make(stamp_ns=time.time_ns(), mode=body.mode)
        return _reply(await gs.send(keys.VEHICLE_MODE, msg, vessel))

    @r.post("/vessels/{vessel}/scenario", response_model=CommandReply, dependencies=command,
            responses={**_command_responses(CommandReply),
                       404: _errors("vessel never seen, or no scenario of that name")},
            tags=["sim"], summary="Load or restart the simulated scenario")
    async def scenario(vessel: VesselName, body: bodies.ScenarioBody) -> JSONResponse:
        """Simulated vessels only (a ``sim`` service alive on the vessel); refused with 409
        otherwise. ``name`` reads ``deploy/scenarios/<name>.toml`` here and sends the document."""
        gs.known(vessel)
        if "sim" not in gs.fleet.services(vessel):
            return _reply(CommandReply(
                vessel=vessel, request=keys.SIM_SCENARIO.suffix, outcome="refused", accepted=False,
                reason=f"vessel {vessel} is not simulated (no sim service is alive on it): "
                       "scenarios apply to simulated vessels only"))
        doc = gs.scenario_document(body.name) if body.name is not None else body.scenario
        try:
            msg = ScenarioRequest.make(stamp_ns=time.time_ns(),
                                       action="restart" if doc is None else "load", scenario=doc)
        except MessageError as err:  # what the message itself refuses (the body checked the rest)
            raise HTTPException(422, f"the scenario cannot be sent: {err}") from None
        return _reply(await gs.send(keys.SIM_SCENARIO, msg, vessel))

    return r


def _recording_error(err: RecordingError) -> HTTPException:
    return HTTPException(err.status, err.detail)


def _replay_router(gs: GroundStation, command: list[Any]) -> APIRouter:
    r = APIRouter(tags=["replay"])

    @r.get("/recordings", response_model=RecordingList, summary="The recordings the replay view can open")
    async def recordings() -> RecordingList:
        """Uploads first, then the runs folder's recordings, newest first."""
        return await run_in_threadpool(gs.library.listing)

    @r.post(UPLOAD_PATH.removeprefix("/api"), response_model=RecordingEntry, dependencies=command,
            summary="Upload an .mcap recording to replay",
            responses={401: _errors("no operator token"), 403: _errors("wrong operator token"),
                       413: _errors("larger than the upload bound"), 415: _errors("not a raw body"),
                       422: _unprocessable("not an MCAP recording that reads"),
                       429: _errors("too many command requests from this identity")},
            openapi_extra={"requestBody": {"required": True, "content": {
                "application/octet-stream": {"schema": {"type": "string", "format": "binary"}}}}})
    async def upload(request: Request, name: Annotated[str, Query(
            min_length=1, max_length=200, description="the file's name, ending .mcap")] = "recording.mcap"
                     ) -> RecordingEntry:
        """The file as the raw request body (``application/octet-stream``), streamed to the ground
        station's upload folder; it needs the operator token because it writes to this machine's
        disk. Kept while the ground station runs (the last few)."""
        ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if ctype != "application/octet-stream":
            raise HTTPException(415, "send the recording as the raw body with Content-Type: "
                                     f"application/octet-stream, not {ctype or 'nothing'}")
        try:
            ref, path = await gs.library.uploads.save(name, request.stream())
            detail = await run_in_threadpool(gs.library.open, ref)
        except RecordingError as err:
            if err.status == 422 and "path" in locals():
                from seaway_groundstation.recordings import remove_upload

                remove_upload(path)
            raise _recording_error(err) from None
        return RecordingEntry(**detail.detail.model_dump(include=set(RecordingEntry.model_fields)))

    @r.get("/recording", response_model=RecordingDetail, summary="Open a recording",
           responses={404: _errors("no such recording"),
                      422: _unprocessable("a name outside the runs folder, or a file that does not read")})
    async def recording(id: RecordingId) -> RecordingDetail:
        """Its span, vessels and number of frames, the missions flown (in metres), each vessel's
        origin and the run's report; the frames themselves come from ``/api/recording/frames``."""
        try:
            return (await run_in_threadpool(gs.library.open, id)).current()
        except RecordingError as err:
            raise _recording_error(err) from None

    @r.get("/recording/frames", summary="A recording's frames over a span of its time",
           responses={200: {"description": "{id, start_s, end_s, loaded_to_s, complete, duration_s, "
                                           "count, frames: [{t_s, frame}]}, each frame as the live "
                                           "stream sends it"},
                      404: _errors("no such recording"), 422: _unprocessable("a bad name or span")})
    async def frames(id: RecordingId,
                     start_s: Annotated[float, Query(ge=0, le=1e7, description="from [s]")] = 0.0,
                     end_s: Annotated[float, Query(gt=0, le=1e7, description="until [s], excluded")] = 60.0
                     ) -> Response:
        """The frames with ``start_s <= t_s < loaded_to_s`` (seconds since the recording's start),
        each exactly what the live stream would have sent then: the page feeds both to the same
        code. The frames are cut as the recording is read: the answer waits a little for them up
        to ``end_s``, then gives those cut so far; ``loaded_to_s`` (``end_s`` once they all are)
        says up to when it is whole, where the next request takes up."""
        if end_s <= start_s:
            raise HTTPException(422, f"end_s ({end_s}) must be after start_s ({start_s})")
        try:
            loaded = await run_in_threadpool(gs.library.get, id)
        except RecordingError as err:
            raise _recording_error(err) from None
        await run_in_threadpool(loaded.timeline.wait, end_s, FRAMES_WAIT_S)
        text, count, upto = loaded.timeline.window(start_s, end_s)
        head = json.dumps({"id": id, "start_s": start_s, "end_s": end_s, "loaded_to_s": upto,
                           "complete": loaded.timeline.complete,
                           "duration_s": loaded.detail.duration_s, "count": count})
        return Response(head[:-1] + ',"frames":' + text + "}", media_type="application/json")

    return r


__all__ = ["GroundStation", "create_app"]
