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
from collections.abc import AsyncIterator, Callable

from fastapi import Depends, FastAPI
from fastapi.exceptions import RequestValidationError
from fastapi.middleware.gzip import GZipMiddleware
from seaway.runtime.bus import Bus
from starlette.concurrency import run_in_threadpool

from seaway_groundstation import errors, guard
from seaway_groundstation.limits import BodyLimit
from seaway_groundstation.routes import fleet, missions, page, replay, vehicle
from seaway_groundstation.routes.common import API_VERSION, error_doc, unprocessable_doc
from seaway_groundstation.routes.replay import UPLOAD_PATH
from seaway_groundstation.settings import Settings
from seaway_groundstation.station import GroundStation
from seaway_groundstation.stream import TransportAbort

TAGS = [
    {"name": "fleet", "description": "The vessels seen (health tokens) and their latest messages."},
    {"name": "mission", "description": "Send, import, export, start, pause, resume and abort missions."},
    {"name": "vehicle", "description": "Arm, disarm and change the autopilot's mode."},
    {"name": "sim", "description": "Load or restart the simulated scenario (simulated vessels only)."},
    {"name": "replay", "description": "Recordings under the runs folder (or uploaded) as the live "
                                      "stream's frames, for the page's replay view."},
    {"name": "page", "description": "What the page needs to know about this ground station."},
]


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
                  responses={400: error_doc("a malformed request: a Content-Length that is not a number"),
                             422: unprocessable_doc("an invalid request: the fields at fault (each "
                                                    "input echoed cut short), a body that is not "
                                                    "UTF-8 JSON, or what in the content is wrong")})
    app.state.groundstation = gs
    app.add_exception_handler(RequestValidationError, errors.unprocessable_response)
    # Outermost first on the way in: the body bound before anything reads a body; replay frames
    # (megabytes of JSON for a long run) go out compressed.
    app.add_middleware(GZipMiddleware, minimum_size=4096)
    app.add_middleware(BodyLimit, max_bytes=settings.max_body_bytes,
                       streamed={UPLOAD_PATH: settings.max_upload_bytes})
    app.add_middleware(TransportAbort)  # a stream client that stopped reading can be cut
    command = [Depends(guard.command_dependency(settings, gs.limiter))]
    app.include_router(fleet.router(gs), prefix="/api")
    app.include_router(missions.router(gs, command), prefix="/api")
    app.include_router(vehicle.router(gs, command), prefix="/api")
    app.include_router(replay.router(gs, command), prefix="/api")
    app.include_router(fleet.stream_router(gs), prefix="/api")
    page.add_page(app, settings)
    return app


__all__ = ["GroundStation", "create_app"]
