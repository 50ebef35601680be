"""A recording's run information read back from its attachments (``seaway.recording.runinfo``)."""

from __future__ import annotations

import json
import math

import pytest
from seaway.recording import runinfo
from seaway.vessel.frames import GeoOrigin


def test_mission_attachment_wins_and_geodetic_waypoints_use_the_origin() -> None:
    origin = GeoOrigin(math.radians(47.0), math.radians(8.0), 0.0)
    lat, lon, _ = origin.to_geodetic(10.0, -5.0)
    geo = {"lat_deg": math.degrees(lat), "lon_deg": math.degrees(lon)}
    doc = {"waypoints": [{"x_m": 0.0, "y_m": 0.0}, geo], "coa_radius_m": 2.0, "task_power_w": 1.5}
    atts = {"mission/m.json": json.dumps(doc).encode(),
            "scenario/s.toml": b'[mission]\nwaypoints_m = [[0, 0], [1, 1]]\ncoa_radius_m = 1.0\n'}
    m = runinfo.mission_from_attachments(atts, origin)
    assert m.coa_radius_m == 2.0 and m.task_power_w == 1.5 and m.source == "attachment mission/m.json"
    assert m.waypoints[1] == pytest.approx((10.0, -5.0), abs=1e-6)
    with pytest.raises(ValueError, match="no origin"):
        runinfo.mission_from_attachments(atts, None)
    assert runinfo.mission_from_attachments({"config/x.toml": b"a = 1"}, None) is None
