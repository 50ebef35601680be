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


def _bound_keys(node: object, where: str = "") -> list[str]:
    """Where a JSON Schema holds pydantic's own bound names instead of JSON Schema's keywords."""
    found: list[str] = []
    if isinstance(node, dict):
        found += [f"{where}.{k}" for k in ("gt", "ge", "lt", "le") if k in node]
        for k, v in node.items():
            found += _bound_keys(v, f"{where}.{k}")
    elif isinstance(node, list):
        for i, v in enumerate(node):
            found += _bound_keys(v, f"{where}[{i}]")
    return found


def test_every_schema_states_its_bounds_in_json_schema_keywords() -> None:
    # A bound pydantic cannot translate (one that follows a validator in an Annotated) lands in the
    # schema as "gt": 0, which no JSON Schema validator (nor the ground station's fuzz) reads: the
    # published schema then allows what the model refuses.
    from seaway.contract.missions import MissionSpec
    from seaway_groundstation import bodies

    models = [*m.ALL_MESSAGES, MissionSpec, bodies.MissionBody, bodies.ImportParams]
    bad = [f"{cls.__name__}{path}" for cls in models
           for path in _bound_keys(cls.model_json_schema())]
    assert not bad, bad
    # and the bounds are there: the options' schema says what their checks refuse
    props = m.MissionRequest.model_json_schema()["properties"]
    assert props["coa_radius_m"]["exclusiveMinimum"] == 0
    assert props["coa_radius_m"]["maximum"] == m.MAX_COA_RADIUS_M
    lat = MissionSpec.model_json_schema()["properties"]["waypoints_deg"]
    assert '"minimum": -90' in json.dumps(lat) and '"maximum": 90' in json.dumps(lat)


def test_the_mission_options_are_declared_once() -> None:
    # What people send (a scenario's or mission file's [mission], the ground station's bodies)
    # carries exactly the options of the bus request, with the request's bounds.
    from seaway.contract.missions import MissionSpec
    from seaway_groundstation import bodies

    options = set(m.MISSION_OPTIONS)
    assert options == set(m.MissionRequest.model_fields) - {"stamp_ns", "waypoints", "home"}
    assert options <= set(MissionSpec.model_fields)
    assert options <= set(bodies.MissionParams.model_fields)
    assert options == set(bodies.ImportParams.model_fields) - {"skip_unsupported"}
    for model in (MissionSpec, bodies.MissionParams, bodies.ImportParams):
        schema = model.model_json_schema()["properties"]
        hint = json.dumps(schema["speed_hint_mps"])
        assert f'"maximum": {m.MAX_SPEED_HINT_MPS}' in hint, (model.__name__, hint)
        with pytest.raises(Exception, match="outside the allowed range"):
            model.model_validate({"coa_radius_m": m.MAX_COA_RADIUS_M * 2, "task_power_w": 1.0,
                                  "waypoints_m": [[0, 0], [1, 0]]} if model is MissionSpec else
                                 {"coa_radius_m": m.MAX_COA_RADIUS_M * 2, "task_power_w": 1.0})
