"""Map tiles the ground station serves itself, for a shore with no internet: an MBTiles file.

MBTiles (Mapbox's spec, 1.3) is a SQLite database: ``tiles(zoom_level, tile_column, tile_row,
tile_data)`` with rows numbered TMS-style (row 0 at the south), and ``metadata(name, value)``
whose ``format`` says what the tiles are (png, jpg, webp; pbf vector tiles are refused: the page
draws images). The page asks for the slippy-map numbering (``y`` 0 at the north), so a request's
``y`` is flipped: ``tile_row = 2**z - 1 - y``. Read-only; the standard library's ``sqlite3``.
"""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path

MEDIA_TYPES = {"png": "image/png", "jpg": "image/jpeg", "jpeg": "image/jpeg", "webp": "image/webp"}
"""The MBTiles ``format`` values the page can draw, and the media type each is served as."""
MAX_ZOOM = 24


class TilesError(ValueError):
    """A tiles file that cannot be served: the sentence names the file and what is wrong."""


class MBTiles:
    """One MBTiles file opened read-only; ``tile(z, x, y)`` in the slippy-map numbering."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self._db = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True,
                                       check_same_thread=False)
            rows = dict(self._db.execute("SELECT name, value FROM metadata").fetchall())
            self._db.execute("SELECT zoom_level, tile_column, tile_row, tile_data FROM tiles LIMIT 1")
        except sqlite3.Error as err:
            raise TilesError(f"tiles {self.path}: not an MBTiles file ({err})") from None
        fmt = str(rows.get("format", "png")).lower()
        if fmt not in MEDIA_TYPES:
            self._db.close()
            raise TilesError(f"tiles {self.path}: format {fmt!r} cannot be drawn by the page; "
                             f"raster tiles only ({', '.join(MEDIA_TYPES)})")
        self.media_type = MEDIA_TYPES[fmt]
        self._lock = threading.Lock()

    def tile(self, z: int, x: int, y: int) -> bytes | None:
        """The tile at zoom ``z``, column ``x``, row ``y`` counted from the north; None if absent."""
        if not (0 <= z <= MAX_ZOOM and 0 <= x < 2 ** z and 0 <= y < 2 ** z):
            return None
        with self._lock:
            row = self._db.execute(
                "SELECT tile_data FROM tiles WHERE zoom_level = ? AND tile_column = ? AND tile_row = ?",
                (z, x, 2 ** z - 1 - y)).fetchone()
        return None if row is None else bytes(row[0])

    def close(self) -> None:
        self._db.close()


def is_mbtiles(tiles: str) -> bool:
    """Whether a ``--tiles`` value names an MBTiles file (by its suffix)."""
    return tiles.lower().endswith(".mbtiles")
