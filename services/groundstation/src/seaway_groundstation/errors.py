"""The ground station's 422 answers: FastAPI's validation errors, bounded and always encodable.

FastAPI's own answer (``{"detail": [errors]}``) echoes each error's ``input``: a 64 KiB body came
back whole, a body that is not JSON (bytes: ``application/octet-stream``, ``text/plain``) could
not be encoded at all when it was not UTF-8 (a 500 and a traceback), and a NaN, Infinity or
1e400 read by Python's JSON could not be encoded either. Here each error keeps its ``loc``,
``msg`` and ``type``; its ``input`` is kept only when short, else cut to a prefix; a body that is
not JSON is one error saying what to send; at most ``MAX_ERRORS`` errors are listed.
"""

from __future__ import annotations

import json
import math
from typing import Any

from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import ValidationError
from starlette.requests import Request

MAX_INPUT_CHARS = 64
"""Longest echo of a field's input (its JSON text); a longer one is cut to this prefix."""
MAX_ERRORS = 20
"""Most errors listed in one answer; the rest are counted in a last entry."""
ELLIPSIS = "..."


def _json_safe(value: Any, depth: int = 0) -> Any:
    """``value`` with every non-finite float as its text ('nan', 'inf'), which JSON cannot carry,
    and bytes as their length (they may not be text at all). Below ``MAX_INPUT_CHARS`` levels of
    nesting a value is '...': its text would be cut before it anyway, and a document nested a few
    hundred deep made this recursion (and so the 422) fail with a RecursionError."""
    if depth > MAX_INPUT_CHARS:
        return ELLIPSIS
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    if isinstance(value, bytes | bytearray):
        return f"<{len(value)} bytes>"
    if isinstance(value, dict):
        return {str(k): _json_safe(v, depth + 1) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v, depth + 1) for v in value]
    return value


def bounded_input(value: Any) -> Any:
    """``value`` as echoed in an error: itself when its JSON text is at most ``MAX_INPUT_CHARS``
    long, else the first ``MAX_INPUT_CHARS`` characters of that text followed by '...'."""
    try:
        text = json.dumps(_json_safe(value), ensure_ascii=False, default=str)
    except (TypeError, ValueError):  # e.g. a dict with keys of mixed types: its text will do
        text = json.dumps(repr(value)[: MAX_INPUT_CHARS + 1])
    if len(text) <= MAX_INPUT_CHARS:
        return json.loads(text)  # plain JSON values, whatever the input's Python types
    return text[:MAX_INPUT_CHARS] + ELLIPSIS


def _not_json(request: Request, body: bytes) -> dict[str, Any]:
    ctype = request.headers.get("content-type") or "no Content-Type"
    try:
        body.decode("utf-8")
        what = "text"
    except UnicodeDecodeError:
        what = "binary data (not UTF-8)"
    return {
        "type": "body_not_json",
        "loc": ["body"],
        "input": f"<{len(body)} bytes>",
        "msg": f"the body is {len(body)} bytes of {what} sent as {ctype}: send a JSON object "
        "encoded as UTF-8 with Content-Type: application/json",
    }


def bounded_errors(request: Request, errors: list[Any]) -> list[dict[str, Any]]:
    """``errors`` as answered: inputs bounded, a body of bytes as one error, at most
    ``MAX_ERRORS``."""
    body_error = next(
        (
            e
            for e in errors
            if list(e.get("loc") or [])[:1] == ["body"] and isinstance(e.get("input"), bytes | bytearray)
        ),
        None,
    )
    if body_error is not None:  # the whole body is bytes: one error says it all
        return [_not_json(request, bytes(body_error["input"]))]
    out: list[dict[str, Any]] = []
    for e in errors[:MAX_ERRORS]:
        e = dict(e)
        e.pop("url", None)
        if "input" in e:
            e["input"] = bounded_input(e["input"])
        if "ctx" in e:
            e["ctx"] = {str(k): bounded_input(v) for k, v in dict(e["ctx"]).items()}
        out.append(e)
    if len(errors) > MAX_ERRORS:
        out.append(
            {
                "type": "more_errors",
                "loc": ["body"],
                "msg": f"{len(errors) - MAX_ERRORS} more error(s) not listed",
            }
        )
    return jsonable_encoder(out)


async def unprocessable_response(request: Request, exc: Exception) -> JSONResponse:
    """The exception handler of ``RequestValidationError``: 422 with the bounded errors."""
    assert isinstance(exc, RequestValidationError)
    return JSONResponse(status_code=422, content={"detail": bounded_errors(request, list(exc.errors()))})


def validation_error(err: ValidationError) -> RequestValidationError:
    """A pydantic error met inside an endpoint, as the 422 FastAPI gives for a body."""
    return RequestValidationError(err.errors(include_url=False, include_context=False))
