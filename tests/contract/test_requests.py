"""Issue 14, item 8: any JSON object was a reset. ``{"stamp_ns": 1, "junk": 2}`` on ``sim/scenario``
restarted the scenario, the same on ``nav/reset`` reset the estimator. Now every request says what
it asks for in a required field, and a request with a field it does not define is refused (topics
and replies still ignore unknown fields, so an old reader survives a newer log)."""

from __future__ import annotations

import json

import pytest
from seaway.contract import keys
from seaway.contract import messages as m
from seaway.contract.messages import MessageError

REQUEST_SPECS = [s for s in keys.REGISTRY if s.kind == "query"]
JUNK = {"stamp_ns": 1, "junk": 2}
MINIMAL = {  # the least each request needs: what it asks for
    m.ArmRequest: {"arm": True},
    m.ModeRequest: {"mode": "MANUAL"},
    m.ScenarioRequest: {"action": "restart"},
    m.MissionRequest: {"waypoints": [{"x_m": 0, "y_m": 0}, {"x_m": 1, "y_m": 0}],
                       "coa_radius_m": 1.0, "task_power_w": 0.49},
    m.MissionCommand: {"command": "pause"},
    m.HomeRequest: {"home": "here"},
    m.NavResetRequest: {"keep_origin": True},
}


def test_every_query_key_takes_a_request() -> None:
    assert {s.message for s in REQUEST_SPECS} == set(MINIMAL)
    assert all(issubclass(s.message, m.Request) for s in REQUEST_SPECS)  # type: ignore[arg-type]


@pytest.mark.parametrize("spec", REQUEST_SPECS, ids=lambda s: s.suffix)
def test_junk_is_no_request(spec: keys.KeySpec) -> None:
    cls = spec.message
    assert cls is not None
    with pytest.raises(MessageError, match=r"junk: unknown field, refused"):
        cls.decode(json.dumps(JUNK))
    with pytest.raises(MessageError, match="Field required"):
        cls.decode(b'{"stamp_ns": 1}')  # saying nothing asks for nothing
    assert cls.decode(json.dumps({"stamp_ns": 1, **MINIMAL[cls]})).stamp_ns == 1
    with pytest.raises(MessageError, match="unknown field"):
        cls.decode(json.dumps({"stamp_ns": 1, **MINIMAL[cls], "typo_d": True}))


def test_a_scenario_request_says_load_or_restart() -> None:
    assert m.ScenarioRequest.make(stamp_ns=1, action="restart").scenario is None
    assert m.ScenarioRequest.make(stamp_ns=1, action="load", scenario={"name": "x"}).action == "load"
    with pytest.raises(MessageError, match="action 'load' needs the scenario document"):
        m.ScenarioRequest.make(stamp_ns=1, action="load")
    with pytest.raises(MessageError, match="action 'restart' restarts the current scenario"):
        m.ScenarioRequest.make(stamp_ns=1, action="restart", scenario={"name": "x"})
    with pytest.raises(MessageError, match="action"):
        m.ScenarioRequest.make(stamp_ns=1, action="reset")


def test_topics_and_replies_still_ignore_unknown_fields() -> None:
    for cls, fields in [(m.Reply, {"accepted": True}),
                        (m.MissionStatus, {"state": "active"}),
                        (m.VehicleStatus, {"autopilot": "px4", "link_ok": True, "armed": False,
                                           "mode": "MANUAL"})]:
        assert cls.decode(json.dumps({"stamp_ns": 1, **fields, "added_in_v2": 3})).stamp_ns == 1


def test_mission_ranges_name_the_allowed_range() -> None:
    """Issue 14, item 11: degrees and task power are bounded on the wire, with the range said."""
    base = MINIMAL[m.MissionRequest]
    for field, value, text in [
        ("task_power_w", 0.0, r"0 W is outside the allowed range \(0, 10000\] W"),
        ("task_power_w", 1e300, r"1e\+300 W is outside the allowed range \(0, 10000\] W"),
    ]:
        with pytest.raises(MessageError, match=rf"MissionRequest\.{field}: Value error, {text}"):
            m.MissionRequest.make(stamp_ns=1, **{**base, field: value})
    with pytest.raises(MessageError, match=r"lat_deg: Value error, 95 deg is outside the allowed "
                                           r"range \[-90, 90\] deg"):
        m.MissionRequest.make(stamp_ns=1, **{**base, "waypoints": [
            {"lat_deg": 95, "lon_deg": 8}, {"lat_deg": 47, "lon_deg": 8}]})
    with pytest.raises(MessageError, match=r"lon_deg: Value error, 200 deg is outside"):
        m.MissionRequest.make(stamp_ns=1, **{**base, "waypoints": [
            {"lat_deg": 47, "lon_deg": 200}, {"lat_deg": 47, "lon_deg": 8}]})
