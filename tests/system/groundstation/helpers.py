"""What the ground station's system tests share: HTTP to the real server, and waiting for a port."""

from __future__ import annotations

import contextlib
import json
import re
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from typing import Any


def http_raw(method: str, url: str, body: Any = None, token: str | None = None,
             timeout_s: float = 60.0) -> tuple[int, bytes]:
    """One request (``body`` sent as JSON, ``token`` as the bearer); the status and the raw body,
    an HTTP error included (a refusal is an answer, not an exception)."""
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method=method)
    if data is not None:
        req.add_header("Content-Type", "application/json")
    if token:
        req.add_header("Authorization", f"Bearer {token}")
    try:
        with urllib.request.urlopen(req, timeout=timeout_s) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as err:
        return err.code, err.read()


def http(method: str, url: str, body: Any = None, token: str | None = None,
         timeout_s: float = 60.0) -> tuple[int, Any]:
    """``http_raw`` with the body decoded from JSON."""
    status, raw = http_raw(method, url, body, token, timeout_s)
    return status, json.loads(raw)


ENERGY_UNITS_J = {"J": 1.0, "kJ": 1e3, "MJ": 1e6}


def joules(text: str) -> float:
    """The first energy the page shows in ``text`` ("29.7 kJ (8.25 Wh)"), in joules."""
    m = re.search(r"(-?\d+(?:\.\d+)?) (J|kJ|MJ)\b", text)
    assert m, f"no energy in {text!r}"
    return float(m.group(1)) * ENERGY_UNITS_J[m.group(2)]


def start_groundstation(procs: Any, env: dict[str, str], *args: str) -> tuple[Any, str, str]:
    """A real ``seaway-groundstation`` on an ephemeral port, with ``args`` (``--config FILE``): (its
    process, its base URL, the operator token), read from its address line."""
    from tests.conftest import BIN, wait_for

    gs = procs.start([str(BIN / "seaway-groundstation"), "--port", "0", "--request-timeout-s", "10",
                      *args], env, "groundstation")
    line = wait_for(lambda: re.search(r"groundstation: (http://127\.0\.0\.1:\d+/) token (\S+)",
                                      procs.log(gs)), 60, what="the ground station's address line")
    return gs, line.group(1), line.group(2)


def pumped(page: Any, done: Any, what: str, timeout_s: float = 30.0) -> None:
    """Wait for ``done()`` while Playwright runs its event handlers: it dispatches an event (a
    dialog, say) to its handler only inside one of its own calls, never while Python sleeps."""
    deadline = time.monotonic() + timeout_s
    while not done():
        assert time.monotonic() < deadline, f"timed out after {timeout_s:g} s waiting for {what}"
        page.wait_for_timeout(100)


@contextlib.contextmanager
def playing(put: Callable[[Any], None], make: Callable[[int], Any], period_s: float = 0.2
            ) -> Iterator[None]:
    """Put ``make(k)`` (k = 1, 2, ...) every ``period_s`` on a thread of its own while the block
    runs: a vessel's state at 5 Hz, say, for a page to show."""
    stop = threading.Event()

    def run() -> None:
        k = 0
        while not stop.wait(period_s):
            k += 1
            put(make(k))

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(5)


def vessel_page(browser: Any, base: str, vessel: str) -> tuple[Any, list[str]]:
    """The page at ``base`` once the ground station has seen ``vessel``, and the list its page
    errors go to (a test asserts it stays empty)."""
    from tests.conftest import wait_for

    wait_for(lambda: http("GET", base + f"api/vessels/{vessel}")[0] == 200, 30,
             what="the vessel seen by the ground station")
    page = browser.new_page(viewport={"width": 1500, "height": 1000})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(base)
    return page, errors
