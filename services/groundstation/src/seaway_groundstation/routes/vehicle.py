"""The vehicle: arm, disarm, set the home, change the autopilot's mode, and load or restart the
simulated scenario (simulated vessels only)."""

import time
from typing import Any

from fastapi import APIRouter, HTTPException
from fastapi.responses import JSONResponse
from seaway.contract import keys
from seaway.contract.messages import ArmRequest, MessageError, ModeRequest, ScenarioRequest

from seaway_groundstation import bodies
from seaway_groundstation.routes.common import VesselName, command_responses, error_doc, reply_response
from seaway_groundstation.station import GroundStation
from seaway_groundstation.views import CommandReply


def router(gs: GroundStation, command: list[Any]) -> APIRouter:
    """The vehicle's requests; ``command``: the dependencies of each (token, rate)."""
    r = APIRouter(tags=["vehicle"])

    @r.post("/vessels/{vessel}/arm", response_model=CommandReply, dependencies=command,
            responses=command_responses(CommandReply), summary="Arm the vehicle")
    async def arm(vessel: VesselName, body: bodies.ArmBody | None = None) -> JSONResponse:
        msg = ArmRequest.make(stamp_ns=time.time_ns(), arm=True, force=bool(body and body.force))
        return reply_response(await gs.send(keys.VEHICLE_ARM, msg, vessel))

    @r.post("/vessels/{vessel}/disarm", response_model=CommandReply, dependencies=command,
            responses=command_responses(CommandReply), summary="Disarm the vehicle")
    async def disarm(vessel: VesselName, body: bodies.ArmBody | None = None) -> JSONResponse:
        msg = ArmRequest.make(stamp_ns=time.time_ns(), arm=False, force=bool(body and body.force))
        return reply_response(await gs.send(keys.VEHICLE_ARM, msg, vessel))

    @r.post("/vessels/{vessel}/home", response_model=CommandReply, dependencies=command,
            responses=command_responses(CommandReply), summary="Set the vessel's home")
    async def set_home(vessel: VesselName, body: bodies.HomeBody) -> JSONResponse:
        """Where a return goes, and the home of every mission that gives none (until set: where
        the vessel was armed); refused by the controller outside the operating area."""
        try:
            msg = body.to_request(time.time_ns())
        except bodies.MissionBuildError as err:
            raise HTTPException(422, str(err)) from None
        return reply_response(await gs.send(keys.MISSION_HOME, msg, vessel))

    @r.post("/vessels/{vessel}/mode", response_model=CommandReply, dependencies=command,
            responses=command_responses(CommandReply), summary="Change the autopilot mode")
    async def mode(vessel: VesselName, body: bodies.ModeBody) -> JSONResponse:
        msg = ModeRequest.make(stamp_ns=time.time_ns(), mode=body.mode)
        return reply_response(await gs.send(keys.VEHICLE_MODE, msg, vessel))

    @r.post("/vessels/{vessel}/scenario", response_model=CommandReply, dependencies=command,
            responses={**command_responses(CommandReply),
                       404: error_doc("vessel never seen, or no scenario of that name")},
            tags=["sim"], summary="Load or restart the simulated scenario")
    async def scenario(vessel: VesselName, body: bodies.ScenarioBody) -> JSONResponse:
        """Simulated vessels only (a ``sim`` service alive on the vessel); refused with 409
        otherwise. ``name`` reads ``deploy/scenarios/<name>.toml`` here and sends the document."""
        gs.known(vessel)
        if "sim" not in gs.fleet.services(vessel):
            return reply_response(CommandReply(
                vessel=vessel, request=keys.SIM_SCENARIO.suffix, outcome="refused", accepted=False,
                reason=f"vessel {vessel} is not simulated (no sim service is alive on it): "
                       "scenarios apply to simulated vessels only"))
        doc = gs.scenario_document(body.name) if body.name is not None else body.scenario
        try:
            msg = ScenarioRequest.make(stamp_ns=time.time_ns(),
                                       action="restart" if doc is None else "load", scenario=doc)
        except MessageError as err:  # what the message itself refuses (the body checked the rest)
            raise HTTPException(422, f"the scenario cannot be sent: {err}") from None
        return reply_response(await gs.send(keys.SIM_SCENARIO, msg, vessel))

    return r
