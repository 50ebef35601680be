"""Foxglove Studio itself, opening a recording with Seaway's layout, in Debian's chromium.

Foxglove Studio 1.48 is the last open-source release of Foxglove (MPL-2.0, ``@foxglove/studio-base``
on npm, a prebuilt bundle of the app). ``studio/`` holds its npm lockfile and the page that boots it
as its own web package did (``boot.js``); ``install`` puts it in a cache folder with ``npm ci``,
``open_recording`` serves page, recording (with HTTP ranges, as Foxglove's remote-file source needs)
and layout on loopback, opens them in headless chromium under Playwright, and reports what Foxglove
reported: the player's problems (a channel whose schema it cannot read is one), the panels' titles,
whether the log panel shows the run's log lines, and a screenshot.

Used by ``test_foxglove_studio.py`` and, for docs/foxglove.md's picture, as a command::

    python -m tests.system.foxglove.studio runs/<run>/recording.mcap --out docs/foxglove/layout.png

Its reader of JSON Schemas is the one current Foxglove and Lichtblick still use (``parseJsonSchema``
of ``@foxglove/mcap-support``). Its WebSocket source speaks ``foxglove.websocket.v1`` only, which
``seaway foxglove`` (foxglove-sdk 0.30: ``foxglove.sdk.v1``) does not offer, so the live view is
tested with the protocol's own client instead (``test_foxglove_live.py``).
"""

from __future__ import annotations

import argparse
import datetime as dt
import socket
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from tests.system import npm_cache

STUDIO_DIR = Path(__file__).parent / "studio"
LAYOUT = Path(__file__).resolve().parents[3] / "deploy" / "foxglove" / "seaway.json"
CHROMIUM = Path("/usr/bin/chromium")
ENV_CACHE = "SEAWAY_FOXGLOVE_STUDIO_CACHE"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run",
                 "--use-gl=swiftshader", "--enable-unsafe-swiftshader"]
"""Headless on a machine without a GPU or network: WebGL (the 3D panel) in software."""


class StudioUnavailableError(RuntimeError):
    """Foxglove Studio cannot be installed or run here (no npm, no chromium, npm failed)."""


def install(cache: Path | None = None) -> Path:
    """The folder whose ``node_modules`` holds Foxglove Studio 1.48 and React, installed with
    ``npm ci`` from ``studio/package-lock.json`` on first use (about 36 MB)."""
    try:
        return npm_cache.install(STUDIO_DIR, "node_modules/@foxglove/studio-base/assets/index.js",
                                 ENV_CACHE, "foxglove-studio", cache)
    except npm_cache.NpmUnavailableError as err:
        raise StudioUnavailableError(str(err)) from None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class _Server:
    """Page, Foxglove's bundle, the layout and the recording on one loopback port (a thread)."""

    def __init__(self, modules: Path, recording: Path, layout: Path) -> None:
        import uvicorn
        from starlette.applications import Starlette
        from starlette.responses import FileResponse
        from starlette.routing import Mount, Route
        from starlette.staticfiles import StaticFiles

        def file(path: Path):
            async def serve(_request):
                return FileResponse(path)
            return serve

        nm = modules / "node_modules"
        routes = [
            Route("/", file(STUDIO_DIR / "index.html")),
            Route("/boot.js", file(STUDIO_DIR / "boot.js")),
            Route("/react.production.min.js", file(nm / "react" / "umd" / "react.production.min.js")),
            Route("/react-dom.production.min.js",
                  file(nm / "react-dom" / "umd" / "react-dom.production.min.js")),
            Route("/layout.json", file(layout)),
            # FileResponse answers Range requests (206), which Foxglove's remote-file source uses.
            Route("/recording.mcap", file(recording)),
            Mount("/assets", StaticFiles(directory=nm / "@foxglove" / "studio-base" / "assets")),
        ]
        self.port = _free_port()
        config = uvicorn.Config(Starlette(routes=routes), host="127.0.0.1", port=self.port,
                                log_level="warning")
        self._server = uvicorn.Server(config)
        self._thread = threading.Thread(target=self._server.run, daemon=True)

    def __enter__(self) -> _Server:
        self._thread.start()
        deadline = time.monotonic() + 30
        while not self._server.started:
            if time.monotonic() > deadline or not self._thread.is_alive():
                raise StudioUnavailableError("the page's server did not start")
            time.sleep(0.05)
        return self

    def __exit__(self, *exc: object) -> None:
        self._server.should_exit = True
        self._thread.join(10)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"


def _rfc3339(ns: int) -> str:
    t = dt.datetime.fromtimestamp(ns // 1_000_000_000, tz=dt.UTC)
    return f"{t:%Y-%m-%dT%H:%M:%S}.{ns % 1_000_000_000:09d}Z"


def _time_range_ns(recording: Path) -> tuple[int, int]:
    from mcap.reader import make_reader

    with open(recording, "rb") as f:
        stats = make_reader(f).get_summary().statistics  # type: ignore[union-attr]
    return stats.message_start_time, stats.message_end_time


@dataclass
class StudioView:
    """What Foxglove Studio showed for a recording."""

    problems: list[str] = field(default_factory=list)
    """The player's problems and the page's errors, as Foxglove logged them."""
    text: str = ""
    """The page's text once loaded: panel titles, legends, the topics listed, log rows shown."""

    def topics(self) -> list[str]:
        """The topics the data source sidebar lists."""
        return [t for t in self.text.splitlines() if t.startswith(("foxglove/", "seaway/"))]


def layout_titles(layout: Path = LAYOUT) -> list[str]:
    """The panel titles a layout sets."""
    import json

    return [c["foxglovePanelTitle"] for c in json.loads(layout.read_text())["configById"].values()
            if "foxglovePanelTitle" in c]


def open_recording(recording: Path, layout: Path = LAYOUT, screenshot: Path | None = None,
                   at_fraction: float = 0.5, wait_for: str | None = "INFO][",
                   timeout_s: float = 120.0, viewport: tuple[int, int] = (1600, 1000)) -> StudioView:
    """Open ``recording`` with ``layout`` in Foxglove Studio, at ``at_fraction`` of its time span;
    wait until the page shows ``wait_for`` (default: a row in the log panel, so messages reached
    the panels; None: the data source's first topic) and the plots had a moment to draw;
    ``screenshot`` it if asked."""
    if not CHROMIUM.exists():
        raise StudioUnavailableError("Debian's chromium is not installed (apt-get install chromium; "
                                ".ci/run does)")
    from playwright.sync_api import sync_playwright

    modules = install()
    start_ns, end_ns = _time_range_ns(recording)
    at = _rfc3339(start_ns + int(at_fraction * (end_ns - start_ns)))
    view = StudioView()
    with _Server(modules, recording, layout) as server, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})

            def on_console(msg) -> None:
                if msg.type == "error" and ("Player problem" in msg.text or "boot failed" in msg.text):
                    view.problems.append(msg.text)

            page.on("console", on_console)
            page.on("pageerror", lambda err: view.problems.append(f"page error: {err}"))
            page.goto(f"{server.url}/?ds=remote-file&ds.url={server.url}/recording.mcap"
                      f"&layoutId=seaway&time={at}")
            page.get_by_text(wait_for or "Topics", exact=False).first.wait_for(timeout=timeout_s * 1000)
            page.wait_for_timeout(4000)  # the plots and the 3D scene draw after the first rows
            hint = page.get_by_text("Open settings to configure topics and layers.")
            if hint.count():  # the 3D panel's first-use hint covers the panel's corner
                hint.first.locator("xpath=..").locator("button").first.click()
                page.wait_for_timeout(500)
            view.text = page.locator("body").inner_text()
            if screenshot is not None:
                # The data source sidebar (its button is the first on the left) closes to give the
                # panels the width; the same button opens it again.
                page.mouse.click(25, 25)
                page.wait_for_timeout(2000)
                screenshot.parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(screenshot))
        finally:
            browser.close()
    return view


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.system.foxglove.studio",
                                 description="Open a recording in Foxglove Studio 1.48 with Seaway's "
                                             "layout; print its problems; take a screenshot.")
    ap.add_argument("recording", type=Path, help="a recording.mcap")
    ap.add_argument("--layout", type=Path, default=LAYOUT, help="a Foxglove layout (JSON)")
    ap.add_argument("--out", type=Path, default=None, help="write a screenshot here (PNG)")
    ap.add_argument("--at", type=float, default=0.5,
                    help="where in the recording to stand, as a fraction of its time span (0-1)")
    args = ap.parse_args(argv)
    view = open_recording(args.recording, args.layout, args.out, args.at)
    print(f"panels shown: {', '.join(t for t in layout_titles(args.layout) if t in view.text)}")
    print(f"topics: {len(view.topics())}")
    print(f"problems: {len(view.problems)}")
    for line in view.problems:
        print(f"  {line}")
    return 1 if view.problems else 0


if __name__ == "__main__":
    sys.exit(main())
