"""Map tiles from an MBTiles file the ground station serves itself (offline), made in the test."""

from __future__ import annotations

from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from seaway.runtime.config import parse_service_args
from seaway.runtime.memory_bus import MemoryHub
from seaway.tools.launch.address import ENV_TILES
from seaway.tools.launch.plan import tiles_for
from seaway_groundstation.app import create_app
from seaway_groundstation.config import GroundStationConfig
from seaway_groundstation.service import parser, tiles_of
from seaway_groundstation.settings import Settings

from tests.unit.groundstation.mbtiles_maker import make, png

TOKEN = "test-token-0123456789abcdef"


def test_an_mbtiles_file_is_served_in_the_pages_numbering(tmp_path: Path) -> None:
    # One tile at z 3, x 2, y 1 counted from the north: TMS row 2**3 - 1 - 1 = 6 in the file.
    path = make(tmp_path / "lake.mbtiles", [(3, 2, 1)])
    with TestClient(create_app(MemoryHub().bus("gs"), Settings(token=TOKEN, tiles=str(path)))) as client:
        assert client.get("/api/config").json()["tiles_url"] == "/tiles/{z}/{x}/{y}"
        r = client.get("/tiles/3/2/1")
        assert r.status_code == 200 and r.headers["content-type"] == "image/png"
        assert r.content == png((2, 1, 30))
        assert client.get("/tiles/3/2/6").status_code == 404  # the file's own row number is not it
        assert client.get("/tiles/3/8/1").status_code == 404  # past the zoom's last column
        assert client.get("/tiles/25/0/0").status_code == 422


def test_what_cannot_be_served_is_refused_at_start_naming_the_file(tmp_path: Path) -> None:
    vector = make(tmp_path / "vector.mbtiles", [(0, 0, 0)], fmt="pbf")
    with pytest.raises(ValueError, match=r"vector.mbtiles: format 'pbf'"):
        Settings(token=TOKEN, tiles=str(vector))
    junk = tmp_path / "junk.mbtiles"
    junk.write_bytes(b"not sqlite at all" * 100)
    with pytest.raises(ValueError, match=r"junk.mbtiles: not an MBTiles file"):
        Settings(token=TOKEN, tiles=str(junk))
    with pytest.raises(ValueError, match="neither"):
        Settings(token=TOKEN, tiles=str(tmp_path / "missing.mbtiles"))


def test_the_launcher_hands_its_tiles_to_the_ground_station(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    path = make(tmp_path / "lake.mbtiles", [(0, 0, 0)])
    monkeypatch.chdir(tmp_path)
    assert tiles_for("lake.mbtiles") == str(path.resolve())  # absolute: its process may run elsewhere
    assert tiles_for("https://t.example/{z}/{x}/{y}.png") == "https://t.example/{z}/{x}/{y}.png"
    assert tiles_for(None) is None and tiles_for("") is None
    monkeypatch.setenv(ENV_TILES, str(path))
    _, config = parse_service_args(parser(), [], GroundStationConfig)
    assert tiles_of(config) == str(path)
    _, config = parse_service_args(parser(), ["--tiles", "https://a/{z}/{x}/{y}"], GroundStationConfig)
    assert tiles_of(config) == "https://a/{z}/{x}/{y}"  # the flag over the launcher's
