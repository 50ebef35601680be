"""A tiny MBTiles file for tests: real PNG tiles in a real SQLite database, rows TMS-numbered."""

from __future__ import annotations

import math
import sqlite3
import struct
import zlib
from collections.abc import Iterable
from pathlib import Path


def png(rgb: tuple[int, int, int] = (40, 120, 200), size: int = 4) -> bytes:
    """A ``size`` x ``size`` PNG of one colour."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    raw = b"".join(b"\x00" + bytes(rgb) * size for _ in range(size))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", size, size, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def slippy(lat_deg: float, lon_deg: float, z: int) -> tuple[int, int]:
    """The slippy-map (x, y) of the tile holding a point at zoom ``z`` (y from the north)."""
    n = 2 ** z
    lat = math.radians(lat_deg)
    return (int((lon_deg + 180) / 360 * n),
            int((1 - math.log(math.tan(lat) + 1 / math.cos(lat)) / math.pi) / 2 * n))


def make(path: Path, tiles: Iterable[tuple[int, int, int]], fmt: str = "png") -> Path:
    """An MBTiles file holding a tile at each slippy-map (z, x, y), stored TMS-style."""
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE metadata (name TEXT, value TEXT)")
    db.execute("CREATE TABLE tiles (zoom_level INTEGER, tile_column INTEGER, tile_row INTEGER, "
               "tile_data BLOB)")
    db.executemany("INSERT INTO metadata VALUES (?, ?)", [("name", "test"), ("format", fmt)])
    db.executemany("INSERT INTO tiles VALUES (?, ?, ?, ?)",
                   [(z, x, 2 ** z - 1 - y, png((x % 256, y % 256, z * 10))) for z, x, y in tiles])
    db.commit()
    db.close()
    return path
