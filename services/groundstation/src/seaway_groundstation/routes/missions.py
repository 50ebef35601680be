"""Missions: send one (as a body, or imported from a QGroundControl ``.plan`` or GeoJSON file),
check, parse or export one without sending it, export the last one sent, start it again, and
pause, resume or abort the active one."""

import json
import re
import time
import unicodedata
from typing import Annotated, Any, Literal
from urllib.parse import quote

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.responses import JSONResponse, Response
from pydantic import ValidationError
from seaway import mission_export
from seaway import mission_files as plans
from seaway.contract import keys
from seaway.contract.messages import MissionCommand, MissionRequest
from starlette.datastructures import UploadFile

from seaway_groundstation import bodies, errors, geo, mission_checks
from seaway_groundstation.routes.common import (
    VESSEL_PATTERN,
    VesselName,
    command_responses,
    error_doc,
    reply_response,
    unprocessable_doc,
)
from seaway_groundstation.station import GroundStation
from seaway_groundstation.views import CommandReply, MissionReply, ParsedMission

AREA_NOT_SENT = ("the file's operating area (geoFence and rally points, or GeoJSON area features) "
                 "is not sent: the vessel keeps to the area its run enforces")
"""Listed with an import's left-out items when the file carries an area."""


def left_out(path: plans.ImportedPath) -> list[str]:
    """What a mission sent from the file leaves out of it: the items skipped, and its area (the
    controller enforces its run's), said so that nobody takes the file's fence for that one."""
    return [*path.skipped, *((AREA_NOT_SENT,) if path.area is not None else ())]

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


def router(gs: GroundStation, command: list[Any]) -> APIRouter:
    """The mission requests; ``command``: the dependencies of one that sends (token, rate)."""
    r = APIRouter(tags=["mission"])

    @r.post("/vessels/{vessel}/mission", response_model=MissionReply, dependencies=command,
            responses=command_responses(MissionReply), summary="Send a mission (it starts at once)")
    async def send_mission(vessel: VesselName, body: bodies.MissionBody) -> JSONResponse:
        """Waypoints in local metres or latitude/longitude; the controller validates the mission
        again and starts it from P_0 (``mission/set``)."""
        try:
            req = bodies.mission_from_body(body, time.time_ns(), gs.settings.max_waypoints)
        except bodies.MissionBuildError as err:
            raise HTTPException(422, str(err)) from None
        return await gs.send_mission(vessel, req)

    @r.post("/vessels/{vessel}/mission/import", response_model=MissionReply, dependencies=command,
            responses={**command_responses(MissionReply), 415: error_doc("neither multipart nor JSON")},
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
        return await gs.send_mission(vessel, req, left_out(path))

    @r.post("/missions/check",
            responses={404: error_doc("the vessel named is not known"),
                       413: error_doc("request body over the bound"),
                       422: unprocessable_doc("not a valid mission body")},
            summary="Check a mission before sending it (nothing is sent)")
    async def check_mission(body: mission_checks.MissionCheckBody,
                            vessel: Annotated[str | None, Query(
                                pattern=VESSEL_PATTERN,
                                description="check against this vessel's live state and area "
                                            "(none: at the desk, the run's vessel model)")] = None
                            ) -> JSONResponse:
        """The controller's own check (``seaway mission check``): path length, predicted time and
        energy, battery after, reserve, energy home from the last waypoint, the operating area's
        verdict; ``{"verdict": "ok"|"refused", "reasons": [...], ...}``."""
        if vessel is not None:
            gs.known(vessel)
        try:
            req = bodies.mission_from_body(body, time.time_ns(), gs.settings.max_waypoints)
        except bodies.MissionBuildError as err:
            raise HTTPException(422, str(err)) from None
        out = mission_checks.live_check(req, gs.fleet, vessel, gs.settings.clock(),
                                        gs.settings.model_vessel_file, body.battery_j)
        return JSONResponse(out)

    @r.post("/missions/parse", response_model=ParsedMission,
            responses={404: error_doc("the vessel named is not known"),
                       413: error_doc("request body over the bound"),
                       422: unprocessable_doc("not a mission file")},
            summary="Read a .plan or GeoJSON document into waypoints, sending nothing")
    async def parse_mission(body: bodies.ParseBody,
                            vessel: Annotated[str | None, Query(
                                pattern=VESSEL_PATTERN,
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
        return ParsedMission(source=path.source, skipped=left_out(path), hints=path.hints, area=area,
                             speeds_mps=list(path.speeds_mps),
                             waypoints=[{"lat_deg": a, "lon_deg": b} for a, b in path.points_deg],
                             waypoints_m=None if metres is None else [{"x_m": x, "y_m": y}
                                                                      for x, y in metres])

    @r.post("/missions/export", summary="Write a mission (not sent) as a .plan or GeoJSON file",
            responses={200: {"content": {"application/json": {}, "application/geo+json": {}},
                             "description": "a QGroundControl .plan or a GeoJSON Feature"},
                       404: error_doc("vessel never seen"),
                       409: error_doc("waypoints in metres and no NED origin known"),
                       413: error_doc("request body over the bound"),
                       422: unprocessable_doc("not a valid mission body, or waypoints in metres "
                                              "too far from the origin to convert")})
    async def export_draft(body: bodies.MissionBody,
                           vessel: Annotated[str | None, Query(
                               pattern=VESSEL_PATTERN,
                               description="whose NED origin converts waypoints in metres")] = None,
                           format: Annotated[Literal["plan", "geojson"], Query()] = "plan") -> Response:
        """The page's mission being edited, as a file, sending nothing. Metres go through the
        vessel's origin (else the run's)."""
        if vessel is not None:
            gs.known(vessel)
        origin = gs.fleet.geo_origin(vessel) if vessel is not None else gs.settings.default_origin
        try:
            req = bodies.mission_from_body(body, time.time_ns(), gs.settings.max_waypoints)
        except bodies.MissionBuildError as err:
            raise HTTPException(422, str(err)) from None
        return _mission_file(req, origin, vessel or "mission", format)

    @r.get("/vessels/{vessel}/mission/export", summary="The last mission sent, as a file",
           responses={200: {"content": {"application/json": {}, "application/geo+json": {}},
                            "description": "a QGroundControl .plan or a GeoJSON Feature"},
                      404: error_doc("vessel never seen, or no mission sent to it from here"),
                      409: error_doc("waypoints in metres and no NED origin known"),
                      422: unprocessable_doc("not a valid format, or the mission's waypoints in "
                                             "metres too far from the origin to convert")})
    async def export_mission(vessel: VesselName,
                             format: Annotated[Literal["plan", "geojson"], Query()] = "plan") -> Response:
        gs.known(vessel)
        req = gs.fleet.last_mission(vessel)
        if req is None:
            raise HTTPException(404, f"no mission has been sent to {vessel} from this ground station")
        return _mission_file(req, gs.fleet.geo_origin(vessel), vessel, format)

    @r.post("/vessels/{vessel}/mission/start", response_model=MissionReply, dependencies=command,
            responses=command_responses(MissionReply),
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
                dependencies=command, responses=command_responses(CommandReply),
                summary=f"{name.capitalize()} the active mission", name=f"mission_{name}")
        async def handler(vessel: VesselName) -> JSONResponse:
            msg = MissionCommand.make(stamp_ns=time.time_ns(), command=name)
            return reply_response(await gs.send(keys.MISSION_COMMAND, msg, vessel))

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
    except bodies.RangeError as err:
        raise HTTPException(422, str(err)) from None
    if format == "plan":
        doc, media, ext = mission_export.to_plan(points, coa_radius_m=req.coa_radius_m,
                                        cruise_speed_mps=req.speed_hint_mps), "application/json", "plan"
    else:
        doc, media, ext = mission_export.to_geojson(points, bodies.mission_properties(req)), \
            "application/geo+json", "geojson"
    return Response(json.dumps(doc, indent=2), media_type=media,
                    headers={"Content-Disposition": content_disposition(
                        f"{vessel}-{req.mission_id or 'mission'}", ext)})


_UNSAFE_FILENAME = re.compile(r"[^A-Za-z0-9_.-]+")


def content_disposition(stem: str, ext: str) -> str:
    """An attachment header naming the file ``<stem>.<ext>`` that any client can read:
    ``filename=`` keeps only ``[A-Za-z0-9_.-]`` of the stem, accents dropped ("mission" if nothing
    is left), since a mission_id is free text (a character outside latin-1 made the header
    unencodable, a 500, and a CR/LF made the server drop the connection); ``filename*=`` (RFC
    5987/6266) gives the real name, UTF-8 and percent-encoded, for the clients that read it."""
    ascii_stem = unicodedata.normalize("NFKD", stem).encode("ascii", "ignore").decode("ascii")
    safe = _UNSAFE_FILENAME.sub("_", ascii_stem).strip("._") or "mission"  # "Süd" -> "Sud"
    real = quote(f"{stem}.{ext}", safe="")
    return f"attachment; filename=\"{safe}.{ext}\"; filename*=UTF-8''{real}"


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
