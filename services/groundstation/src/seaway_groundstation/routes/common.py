"""What the ground station's routers share: the API version, the vessel name as a path or query
parameter, the answers each operation documents, and a vessel's reply as a response."""

from typing import Annotated, Any

from fastapi import Path as PathParam
from fastapi.responses import JSONResponse
from pydantic import BaseModel

from seaway_groundstation.station import STATUS_OF_OUTCOME
from seaway_groundstation.views import CommandReply, ErrorBody, UnprocessableBody

API_VERSION = "1"
VESSEL_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$"
"""A vessel's name: the key namespace ``seaway/<vessel>/...`` (``keys.check_vessel``)."""
VesselName = Annotated[str, PathParam(pattern=VESSEL_PATTERN, examples=["vessel1"],
                                      description="vessel name (the key namespace seaway/<vessel>/...)")]


def error_doc(description: str) -> dict[str, Any]:
    """An error answer for the schema: ``{"detail": ...}``, saying when."""
    return {"model": ErrorBody, "description": description}


def unprocessable_doc(description: str) -> dict[str, Any]:
    """A 422 answer for the schema: the fields at fault, saying when."""
    return {"model": UnprocessableBody, "description": description}


def command_responses(reply_model: type[BaseModel]) -> dict[int | str, dict[str, Any]]:
    """The answers of a request that becomes a bus request to a vessel (``reply_model``: its body)."""
    return {
        401: error_doc("no operator token (Authorization: Bearer <token>)"),
        403: error_doc("wrong operator token"),
        404: error_doc("vessel never seen"),
        409: {"model": reply_model, "description": "refused by the vessel; the reason says why"},
        413: error_doc("request body over the bound"),
        429: error_doc("too many command requests from this identity: the operator, or this "
                       "address without the token (see Retry-After)"),
        502: {"model": reply_model, "description": "the transport answered with an error"},
        504: {"model": reply_model, "description": "nobody answered in time (service not running?)"},
    }


def reply_response(reply: CommandReply) -> JSONResponse:
    """The vessel's reply, with the status its outcome stands for (``STATUS_OF_OUTCOME``)."""
    return JSONResponse(reply.model_dump(mode="json"), status_code=STATUS_OF_OUTCOME[reply.outcome])
