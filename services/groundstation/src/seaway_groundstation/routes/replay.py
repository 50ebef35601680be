"""Replay: the recordings under the runs folder or uploaded, opened, and cut into the live stream's
frames over a span of their time, for the page's replay view."""

import json
from typing import Annotated, Any

from fastapi import APIRouter, HTTPException, Query, Request
from fastapi.responses import Response
from starlette.concurrency import run_in_threadpool

from seaway_groundstation.recordings import RecordingDetail, RecordingEntry, RecordingError, RecordingList
from seaway_groundstation.routes.common import error_doc, unprocessable_doc
from seaway_groundstation.station import GroundStation

UPLOAD_PATH = "/api/recordings/upload"
FRAMES_WAIT_S = 2.0
"""How long a frames request waits for frames not yet cut [s] before it answers with fewer."""
MAX_FRAMES_BYTES = 4 << 20
"""Frames' text in one answer at most [bytes] (some 2000 frames of a vessel, minutes of recorded
time): a span asked for with more ends earlier (``loaded_to_s``), where the page takes up. An hour
of one vessel is some 65 MB of frames; a whole recording in one body was that in the server's
memory two or three times over, per request."""
RecordingId = Annotated[str, Query(
    min_length=1, max_length=600, examples=["20260101-120000-sim-lake-cc-empc"],
    description="a recording's id from GET /api/recordings: its path under the runs folder, or upload:...")]


def _recording_error(err: RecordingError) -> HTTPException:
    return HTTPException(err.status, err.detail)


def router(gs: GroundStation, command: list[Any]) -> APIRouter:
    """The replay view's requests; ``command``: the dependencies of an upload (token, rate)."""
    r = APIRouter(tags=["replay"])

    @r.get("/recordings", response_model=RecordingList, summary="The recordings the replay view can open")
    async def recordings() -> RecordingList:
        """Uploads first, then the runs folder's recordings, newest first."""
        return await run_in_threadpool(gs.library.listing)

    @r.post(UPLOAD_PATH.removeprefix("/api"), response_model=RecordingEntry, dependencies=command,
            summary="Upload an .mcap recording to replay",
            responses={401: error_doc("no operator token"), 403: error_doc("wrong operator token"),
                       413: error_doc("larger than the upload bound"), 415: error_doc("not a raw body"),
                       422: unprocessable_doc("not an MCAP recording that reads"),
                       429: error_doc("too many command requests from this identity"),
                       507: error_doc("no room on the ground station's disk for it")},
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
           responses={404: error_doc("no such recording"),
                      422: unprocessable_doc("a name outside the runs folder, or a file that does not read")})
    async def recording(id: RecordingId) -> RecordingDetail:
        """Its span, vessels and number of frames, the missions flown (in metres), each vessel's
        origin and the run's report; the frames themselves come from ``/api/recording/frames``."""
        try:
            return (await run_in_threadpool(gs.library.open, id)).current()
        except RecordingError as err:
            raise _recording_error(err) from None

    @r.get("/recording/frames", summary="A recording's frames over a span of its time",
           responses={200: {"description": "{id, start_s, end_s, loaded_to_s, complete, duration_s, "
                                           "count, error, frames: [{t_s, frame}]}, each frame as the "
                                           "live stream sends it"},
                      404: error_doc("no such recording"), 422: unprocessable_doc("a bad name or span")})
    async def frames(id: RecordingId,
                     start_s: Annotated[float, Query(ge=0, le=1e7, description="from [s]")] = 0.0,
                     end_s: Annotated[float, Query(gt=0, le=1e7, description="until [s], excluded")] = 60.0
                     ) -> Response:
        """The frames with ``start_s <= t_s < loaded_to_s`` (seconds since the recording's start),
        each exactly what the live stream would have sent then: the page feeds both to the same
        code. The frames are cut as the recording is read: the answer waits a little for them up
        to ``end_s``, then gives those cut so far, at most ``MAX_FRAMES_BYTES`` of them;
        ``loaded_to_s`` (``end_s`` once they all are) says up to when it is whole, where the next
        request takes up. ``error``: why the frames stop before the recording's end (a damaged
        chunk: the recording, what is wrong and how to repair it), else null."""
        if end_s <= start_s:
            raise HTTPException(422, f"end_s ({end_s}) must be after start_s ({start_s})")
        try:
            loaded = await run_in_threadpool(gs.library.get, id)
        except RecordingError as err:
            raise _recording_error(err) from None
        await run_in_threadpool(loaded.timeline.wait, end_s, FRAMES_WAIT_S)
        text, count, upto = await run_in_threadpool(loaded.timeline.window, start_s, end_s,
                                                    MAX_FRAMES_BYTES)  # read from disk
        head = json.dumps({"id": id, "start_s": start_s, "end_s": end_s, "loaded_to_s": upto,
                           "complete": loaded.timeline.complete,
                           "duration_s": loaded.detail.duration_s, "count": count,
                           "error": loaded.error})
        return Response(head[:-1].encode() + b',"frames":' + text + b"}", media_type="application/json")

    return r
