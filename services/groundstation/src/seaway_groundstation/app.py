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
                 "origin": {... NavOrigin ...}}}

with only the kinds that changed since the client's last frame (the latest of each, never a
backlog; ``stream.py`` says how a slow client is kept from slowing the others).
"""

import asyncio
import contextlib
import json
import math
import secrets
import time
from collections.abc import AsyncIterator, Callable
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, FastAPI, HTTPException, Query, Request
from fastapi import Path as PathParam
from fastapi.exceptions import RequestValidationError
from fastapi.responses import HTMLResponse, JSONResponse, Response
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from pydantic import BaseModel, ValidationError
from seaway.contract import keys
from seaway.contract.config import ConfigError, deploy_path, read_document
from seaway.contract.messages import (
    ArmRequest,
    Message,
    MissionCommand,
    MissionRequest,
    ModeRequest,
    ScenarioRequest,
)
from seaway.runtime.bus import Bus
from starlette.concurrency import run_in_threadpool
from starlette.datastructures import UploadFile
from starlette.websockets import WebSocket

from seaway_groundstation import bodies, plans
from seaway_groundstation.fleet import Fleet
from seaway_groundstation.gateway import BusLink, ask
from seaway_groundstation.limits import BodyLimit, RateLimiter
from seaway_groundstation.settings import Settings
from seaway_groundstation.stream import StreamHub
from seaway_groundstation.views import (
    CommandReply,
    ErrorBody,
    FleetView,
    MissionReply,
    ParsedMission,
    VesselView,
)

API_VERSION = "1"
STATUS_OF_OUTCOME = {"accepted": 200, "refused": 409, "no_reply": 504, "error_reply": 502}
VesselName = Annotated[str, PathParam(pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$",
                                      description="vessel name (the key namespace seaway/<vessel>/...)")]
TAGS = [
    {"name": "fleet", "description": "The vessels seen (health tokens) and their latest messages."},
    {"name": "mission", "description": "Send, import, export, start, pause, resume and abort missions."},
    {"name": "vehicle", "description": "Arm, disarm and change the autopilot's mode."},
    {"name": "sim", "description": "Load or restart the simulated scenario (simulated vessels only)."},
]


def _errors(description: str) -> dict[str, Any]:
    return {"model": ErrorBody, "description": description}


def _command_responses(reply_model: type[BaseModel]) -> dict[int | str, dict[str, Any]]:
    return {
        401: _errors("no operator token (Authorization: Bearer <token>)"),
        403: _errors("wrong operator token"),
        404: _errors("vessel never seen"),
        409: {"model": reply_model, "description": "refused by the vessel; the reason says why"},
        413: _errors("request body over the bound"),
        429: _errors("too many command requests from this client (see Retry-After)"),
        502: {"model": reply_model, "description": "the transport answered with an error"},
        504: {"model": reply_model, "description": "nobody answered in time (service not running?)"},
    }


class GroundStation:
    """What the endpoints share: the bus, the fleet, the stream hub, the limits, the last missions."""

    def __init__(self, bus: Bus, settings: Settings) -> None:
        self.bus, self.settings = bus, settings
        self.fleet = Fleet(settings.stale_after_s)
        self.hub = StreamHub(self.fleet, settings.stream_rate_hz, settings.max_stream_clients,
                             settings.clock)
        self.link = BusLink(bus, self.fleet, settings.clock, self.hub.notify)
        self.limiter = RateLimiter(settings.rate_limit_per_s, settings.rate_limit_burst)

    def known(self, vessel: str) -> None:
        if not self.fleet.knows(vessel):
            seen = ", ".join(self.fleet.vessels()) or "none yet"
            raise HTTPException(404, f"vessel {vessel!r} has not been seen (no health token or "
                                     f"message from it); vessels seen: {seen}")

    async def send(self, spec: keys.KeySpec, msg: Message, vessel: str) -> CommandReply:
        self.known(vessel)
        return await run_in_threadpool(ask, self.bus, spec, msg, vessel, self.settings.request_timeout_s)

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


def _validation_error(err: ValidationError) -> RequestValidationError:
    return RequestValidationError(err.errors(include_url=False, include_context=False))


def _operator_dependency(gs: GroundStation) -> Callable[..., Any]:
    bearer = HTTPBearer(auto_error=False, scheme_name="operator token",
                        description="the operator token the ground station prints at start")
    expected = gs.settings.token.encode()

    async def operator(creds: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]) -> None:
        if creds is None:
            raise HTTPException(401, "this request moves or changes a vessel: send "
                                     "'Authorization: Bearer <operator token>' (the ground station "
                                     "prints it at start)", headers={"WWW-Authenticate": "Bearer"})
        if not secrets.compare_digest(creds.credentials.encode(), expected):
            raise HTTPException(403, "wrong operator token")

    return operator


def _rate_dependency(gs: GroundStation) -> Callable[..., Any]:
    async def rate_limit(request: Request) -> None:
        client = request.client.host if request.client else "unknown"
        wait_s = gs.limiter.allow(client, gs.settings.clock())
        if wait_s > 0:
            retry = "3600" if math.isinf(wait_s) else str(max(1, math.ceil(wait_s)))
            raise HTTPException(429, f"too many command requests from {client}: at most "
                                     f"{gs.settings.rate_limit_burst} at once, then "
                                     f"{gs.settings.rate_limit_per_s:g} per second",
                                headers={"Retry-After": retry})

    return rate_limit


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

    app = FastAPI(title="Seaway ground station", version=API_VERSION, lifespan=lifespan,
                  description=__doc__, openapi_tags=TAGS, docs_url=None, redoc_url=None)
    app.state.groundstation = gs
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes)
    command = [Depends(_rate_dependency(gs)), Depends(_operator_dependency(gs))]
    app.include_router(_read_router(gs), prefix="/api")
    app.include_router(_mission_router(gs, command), prefix="/api")
    app.include_router(_vehicle_router(gs, command), prefix="/api")

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

    @app.get("/", include_in_schema=False)
    async def index() -> HTMLResponse:
        return HTMLResponse("<!doctype html><title>Seaway ground station</title>"
                            "<h1>Seaway ground station</h1><p>API: <a href='/api/vessels'>/api/vessels"
                            "</a>, schema: <a href='/openapi.json'>/openapi.json</a>, live stream: "
                            "WebSocket /api/stream.</p>")

    return app


def _read_router(gs: GroundStation) -> APIRouter:
    r = APIRouter(tags=["fleet"])

    @r.get("/vessels", response_model=FleetView, summary="Every vessel seen, with its latest messages")
    async def vessels() -> FleetView:
        return gs.fleet.views(gs.settings.clock())

    @r.get("/vessels/{vessel}", response_model=VesselView, summary="One vessel",
           responses={404: _errors("vessel never seen")})
    async def one_vessel(vessel: VesselName) -> VesselView:
        view = gs.fleet.view(vessel, gs.settings.clock())
        if view is None:
            gs.known(vessel)
        assert view is not None
        return view

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
        return await gs.send_mission(vessel, bodies.mission_from_body(body, time.time_ns()))

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

    @r.post("/missions/parse", response_model=ParsedMission,
            responses={413: _errors("request body over the bound"), 422: _errors("not a mission file")},
            summary="Read a .plan or GeoJSON document into waypoints, sending nothing")
    async def parse_mission(body: bodies.ParseBody) -> ParsedMission:
        try:
            path = plans.parse_document(body.document, skip_unsupported=body.skip_unsupported,
                                        max_waypoints=gs.settings.max_waypoints)
        except plans.PlanError as err:
            raise HTTPException(422, str(err)) from None
        return ParsedMission(source=path.source, skipped=list(path.skipped), hints=path.hints,
                             waypoints=[{"lat_deg": a, "lon_deg": b} for a, b in path.points_deg])

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
        origin = bodies.geo_origin(gs.fleet.origin(vessel)) or gs.settings.default_origin
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
            raise _validation_error(err) from None
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
            body = bodies.ImportBody.model_validate(raw)
        except ValidationError as err:
            raise _validation_error(err) from None
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
        msg = ScenarioRequest.make(stamp_ns=time.time_ns(), scenario=doc)
        return _reply(await gs.send(keys.SIM_SCENARIO, msg, vessel))

    return r


__all__ = ["GroundStation", "create_app"]
