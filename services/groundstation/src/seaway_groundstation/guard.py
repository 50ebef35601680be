"""Who may command, and how often: the dependency every command endpoint takes.

A command needs the operator token (``Authorization: Bearer <token>``): 401 without it, 403 with
a wrong one. The command rate (``RateLimiter``, 429 past it) is kept per identity: the operator
(whoever holds the token, from any address) has one bucket, and requests without the right token
have their own bucket per client address, counted before they are refused. So a client guessing
tokens is slowed down, and requests without the token never use up the operator's commands.
"""

# No ``from __future__ import annotations``: FastAPI reads the dependency's annotations at
# run time, and they name a local (``bearer``).
import contextvars
import math
import re
import secrets
from collections.abc import Callable
from typing import Annotated, Any

from fastapi import Depends, HTTPException, Request
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer

from seaway_groundstation.limits import RateLimiter
from seaway_groundstation.settings import Settings

OPERATOR = "operator"
"""The rate limit's key of requests carrying the operator token."""
CLIENT_HEADER = "X-Seaway-Client"
"""The header a page names itself by (a random id per page load), so the others can tell its
commands from their own."""
CLIENT_ID = re.compile(r"[A-Za-z0-9_-]{1,64}")
commander: contextvars.ContextVar[str] = contextvars.ContextVar("commander", default="")
"""The current command's ``CLIENT_HEADER`` ('' without one), set by the command dependency for the
endpoint it guards (the same task, so the endpoint reads it)."""
UNAUTHENTICATED = "unauthenticated:"
"""The rate limit's key prefix of requests without the right token (then the client's address)."""


def rate_key(token_ok: bool, client: str) -> str:
    """The bucket a command request counts against: the operator's, or its address's own."""
    return OPERATOR if token_ok else UNAUTHENTICATED + client


def command_dependency(settings: Settings, limiter: RateLimiter) -> Callable[..., Any]:
    """The FastAPI dependency of a command: the rate limit of the caller's identity, then the
    token (see the module's description)."""
    bearer = HTTPBearer(
        auto_error=False,
        scheme_name="operator token",
        description="the operator token the ground station prints at start",
    )
    expected = settings.token.encode()

    async def command(
        request: Request, creds: Annotated[HTTPAuthorizationCredentials | None, Depends(bearer)]
    ) -> None:
        client = request.client.host if request.client else "unknown"
        token_ok = creds is not None and secrets.compare_digest(creds.credentials.encode(), expected)
        wait_s = limiter.allow(rate_key(token_ok, client), settings.clock())
        if wait_s > 0:
            who = "the operator" if token_ok else f"{client} without the operator token"
            retry = "3600" if math.isinf(wait_s) else str(max(1, math.ceil(wait_s)))
            raise HTTPException(
                429,
                f"too many command requests from {who}: at most "
                f"{settings.rate_limit_burst} at once, then "
                f"{settings.rate_limit_per_s:g} per second",
                headers={"Retry-After": retry},
            )
        if creds is None:
            raise HTTPException(
                401,
                "this request moves or changes a vessel: send "
                "'Authorization: Bearer <operator token>' (the ground station "
                "prints it at start)",
                headers={"WWW-Authenticate": "Bearer"},
            )
        if not token_ok:
            raise HTTPException(403, "wrong operator token")
        client_id = request.headers.get(CLIENT_HEADER, "")
        if client_id and not CLIENT_ID.fullmatch(client_id):
            raise HTTPException(422, f"header {CLIENT_HEADER}: 1 to 64 letters, digits, '_' or '-', "
                                     f"got {client_id[:64]!r}")
        commander.set(client_id)

    return command
