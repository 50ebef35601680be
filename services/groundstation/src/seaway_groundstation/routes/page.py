"""The page: its files (plain HTML, CSS and ES modules shipped in the package) at ``/static``, the
page itself at ``/``, and the map tiles the ground station serves itself at ``/tiles/`` (from an
MBTiles file or a folder; a tile URL is the page's to fetch). None of it is in the schema."""

import importlib.resources
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, FastAPI, HTTPException
from fastapi import Path as PathParam
from fastapi.responses import FileResponse, Response
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool

from seaway_groundstation import tiles
from seaway_groundstation.settings import Settings

STATIC = importlib.resources.files("seaway_groundstation") / "static"
"""The page: plain HTML, CSS and ES modules shipped in the package (no build step, no CDN)."""


def add_page(app: FastAPI, settings: Settings) -> None:
    """Mount the page's files at ``/static``, then serve the page and the tiles (``router``)."""
    with importlib.resources.as_file(STATIC) as static_dir:
        index_html = Path(static_dir) / "index.html"
        app.mount("/static", StaticFiles(directory=static_dir), name="static")
    app.include_router(router(index_html, settings))


def router(index_html: Path, settings: Settings) -> APIRouter:
    """The page at ``/`` and, when ``settings.tiles`` is an MBTiles file or a folder, its tiles."""
    r = APIRouter(include_in_schema=False)

    @r.get("/", include_in_schema=False)
    async def index() -> FileResponse:
        # no-cache: a ground station updated in place serves its new page at the next load
        return FileResponse(index_html, headers={"Cache-Control": "no-cache"})

    if settings.tiles is not None and tiles.is_mbtiles(settings.tiles):
        mbtiles = tiles.MBTiles(settings.tiles)

        @r.get("/tiles/{z}/{x}/{y}", include_in_schema=False)
        async def mb_tile(z: Annotated[int, PathParam(ge=0, le=tiles.MAX_ZOOM)],
                          x: Annotated[int, PathParam(ge=0)], y: Annotated[int, PathParam(ge=0)]) -> Response:
            data = await run_in_threadpool(mbtiles.tile, z, x, y)
            if data is None:
                raise HTTPException(404, f"no tile {z}/{x}/{y} in {mbtiles.path.name}")
            return Response(data, media_type=mbtiles.media_type,
                            headers={"Cache-Control": "max-age=3600"})
    elif settings.tiles is not None and not settings.tiles.startswith(("http://", "https://")):
        tiles_dir = Path(settings.tiles).resolve()

        @r.get("/tiles/{z}/{x}/{y}.png", include_in_schema=False)
        async def tile(z: Annotated[int, PathParam(ge=0, le=24)], x: Annotated[int, PathParam(ge=0)],
                       y: Annotated[int, PathParam(ge=0)]) -> FileResponse:
            path = tiles_dir / str(z) / str(x) / f"{y}.png"
            if x >= 2 ** z or y >= 2 ** z or not path.is_file():
                raise HTTPException(404, f"no tile {z}/{x}/{y} in the tiles folder")
            return FileResponse(path, media_type="image/png")

    return r
