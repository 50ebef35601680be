"""The fleet's reading side: the vessels seen with their latest messages, the live metrics of a
vessel's mission, the page's settings, and the live stream of frames (WebSocket ``/api/stream``,
its frame documented in ``seaway_groundstation.app``)."""

from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, HTTPException, Query
from pydantic import BaseModel, Field
from seaway.contract import keys
from starlette.concurrency import run_in_threadpool
from starlette.websockets import WebSocket

from seaway_groundstation.progress import MetricsView
from seaway_groundstation.routes.common import API_VERSION, VesselName, error_doc
from seaway_groundstation.station import GroundStation
from seaway_groundstation.views import FleetView, VesselView


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
    shore_health_prefix: str = Field(
        default=keys.SHORE_HEALTH_PREFIX, description="a service whose health token starts with "
        "this runs on the shore computer (its recorder, router, page), not on the vessel")


def router(gs: GroundStation) -> APIRouter:
    """The fleet's reading requests (open: no token) and the page's settings."""
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
           responses={404: error_doc("vessel never seen")})
    async def one_vessel(vessel: VesselName) -> VesselView:
        gs.known(vessel)
        gs.learn_mission(vessel)
        view = gs.fleet.view(vessel, gs.settings.clock())
        assert view is not None  # known vessels have a view
        return view

    @r.get("/vessels/{vessel}/metrics", response_model=MetricsView | None,
           summary="The paper's metrics of the current mission so far",
           responses={404: error_doc("vessel never seen"),
                      409: error_doc("the samples heard cannot make metrics (a span over "
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


def close_reason(text: str) -> str:
    """``text`` cut to a WebSocket close frame's reason: at most 123 bytes of UTF-8 (a vessel
    name given may be any text; cutting characters could leave it over the bound)."""
    return text.encode("utf-8")[:123].decode("utf-8", "ignore")


def stream_router(gs: GroundStation) -> APIRouter:
    """The live stream: ``/stream?vessel=NAME`` (repeatable; none: every vessel)."""
    r = APIRouter()

    @r.websocket("/stream")
    async def stream(websocket: WebSocket, vessel: Annotated[list[str] | None, Query()] = None) -> None:
        wanted = None
        if vessel:
            try:
                wanted = frozenset(keys.check_vessel(v) for v in vessel)
            except keys.KeyNameError as err:
                # Accepted, then closed with the reason: a close before the handshake reaches
                # the client as a bare HTTP 403, as if it lacked authority.
                await websocket.accept()
                await websocket.close(code=1008, reason=close_reason(str(err)))
                return
        await gs.hub.serve(websocket, wanted)

    return r
