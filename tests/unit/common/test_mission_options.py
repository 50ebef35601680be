"""A mission's options: the request's ``predict_disturbance``, MissionSpec's overrides, scenario files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from seaway import mission_export, mission_files
from seaway.contract.config import ConfigError, deploy_path
from seaway.contract.messages import MessageError, MissionRequest, Waypoint
from seaway.contract.missions import MissionSpec
from seaway.simkit.scenario import load_mission, load_scenario

WPS = [[0.0, 0.0], [8.0, 0.0]]


def spec(**kw) -> MissionSpec:
    return MissionSpec(waypoints_m=WPS, coa_radius_m=1.0, task_power_w=0.49, **kw)


def request(**kw) -> MissionRequest:
    fields = {"stamp_ns": 1, "waypoints": [Waypoint(x_m=0, y_m=0), Waypoint(x_m=8, y_m=0)],
              "coa_radius_m": 1.0, "task_power_w": 0.49}
    return MissionRequest.make(**{**fields, **kw})


def test_request_predicts_with_tau_d_only_when_asked() -> None:
    assert request().predict_disturbance is False  # the paper's tau_d = 0
    assert request(predict_disturbance=True).predict_disturbance is True
    # An older sender that does not know the field: the paper's behaviour.
    old = json.dumps({"stamp_ns": 1, "waypoints": [{"x_m": 0, "y_m": 0}, {"x_m": 8, "y_m": 0}],
                      "coa_radius_m": 1.0, "task_power_w": 0.49})
    assert MissionRequest.decode(old).predict_disturbance is False
    sent = request(predict_disturbance=True, controller="nmpc")
    back = MissionRequest.decode(sent.encode())
    assert back == sent and back.predict_disturbance and back.controller == "nmpc"
    schema = MissionRequest.json_schema()["properties"]["predict_disturbance"]
    assert schema["type"] == "boolean" and schema["default"] is False
    assert "tau_d = 0" in schema["description"]


@pytest.mark.parametrize(("fields", "problem"), [
    ({"predict_disturbance": "sometimes"}, "MissionRequest.predict_disturbance"),
    ({"predict_disturbance": [True]}, "MissionRequest.predict_disturbance"),
    ({"task_power_w": -0.1}, "MissionRequest.task_power_w"),
    ({"task_power_w": float("nan")}, "MissionRequest.task_power_w"),
    ({"controller": "PID!"}, "MissionRequest.controller"),
])
def test_bad_request_fields_are_refused_naming_them(fields: dict, problem: str) -> None:
    with pytest.raises(MessageError, match=problem):
        request(**fields)


def test_spec_carries_its_own_values_by_default() -> None:
    req = spec().to_request(5, "m")
    assert (req.stamp_ns, req.mission_id, req.controller, req.predict_disturbance,
            req.task_power_w) == (5, "m", "cc-empc", False, 0.49)
    req = spec(predict_disturbance=True, controller="eo-empc").to_request(5)
    assert req.predict_disturbance is True and req.controller == "eo-empc"


def test_spec_overrides_replace_the_missions_values() -> None:
    s = spec(predict_disturbance=True, controller="eo-empc")
    req = s.to_request(5, controller="nmpc", predict_disturbance=False, task_power_w=2.5)
    assert (req.controller, req.predict_disturbance, req.task_power_w) == ("nmpc", False, 2.5)
    # Falsy overrides are overrides too: prediction switched off from on.
    req = s.to_request(5, predict_disturbance=False)
    assert req.predict_disturbance is False
    # None leaves the mission's own value; the positional form (stamp, id, controller) still works.
    req = s.to_request(5, "id", None, predict_disturbance=None, task_power_w=None)
    assert (req.mission_id, req.controller, req.predict_disturbance, req.task_power_w) == (
        "id", "eo-empc", True, 0.49)
    assert s.predict_disturbance is True  # the spec itself is unchanged


@pytest.mark.parametrize("bad", [-1.0, 0.0, 1e300, float("nan"), float("inf")])
def test_a_bad_task_power_override_is_refused(bad: float) -> None:
    """T^w must lie in (0, 10 kW] (``MAX_TASK_POWER_W`` says why): 0 never arrives, 1e300
    overflowed every control step; the error names the field."""
    with pytest.raises(MessageError, match="task_power_w"):
        spec().to_request(5, task_power_w=bad)


def _scenario_with(tmp_path: Path, line: str) -> Path:
    text = deploy_path("scenarios", "paper-c1.toml").read_text()
    assert "\n[mission]\n" in text
    p = tmp_path / "c1-tau.toml"
    p.write_text(text.replace("\n[mission]\n", f"\n[mission]\n{line}\n"))
    return p


def test_a_scenario_mission_may_ask_for_the_prediction(tmp_path: Path) -> None:
    assert load_scenario("paper-c1").mission.predict_disturbance is False  # the paper's
    path = _scenario_with(tmp_path, "predict_disturbance = true")
    sc = load_scenario(path)
    assert sc.mission.predict_disturbance is True
    assert sc.mission.to_request(1, sc.name).predict_disturbance is True
    assert load_mission(path).to_request(1).predict_disturbance is True
    with pytest.raises(ConfigError, match="predict_disturbence: unknown field"):
        load_scenario(_scenario_with(tmp_path, "predict_disturbence = true"))
    with pytest.raises(ConfigError, match="predict_disturbance"):
        load_scenario(_scenario_with(tmp_path, 'predict_disturbance = "often"'))


@pytest.mark.parametrize("field, bad", [
    ("coa_radius_m", -5.0), ("coa_radius_m", 0.0), ("coa_radius_m", 1e308), ("coa_radius_m", 10**400),
    ("speed_hint_mps", 1e300), ("speed_hint_mps", 10**400), ("speed_hint_mps", 0.0)])
def test_the_bus_request_bounds_what_every_sender_may_carry(field: str, bad: float) -> None:
    """The bus contract is the last edge before the controller: r_COA in (0, 10 km], a cruise
    hint in (0, 50] m/s, whichever file or client the request came from. An integer past a
    float's range is a refusal naming the field, not an OverflowError."""
    with pytest.raises(MessageError, match=field):
        request(**{field: bad})


def _geojson(**properties) -> dict:
    return {"type": "Feature", "geometry": {"type": "LineString",
                                            "coordinates": [[8.0, 47.0], [8.001, 47.001]]},
            "properties": properties}


@pytest.mark.parametrize("properties, named", [
    ({"speed_hint_mps": 1e300}, "speed_hint_mps"),
    ({"coa_radius_m": 1e308}, "coa_radius_m"),
    ({"coa_radius_m": -5}, "coa_radius_m"),
])
def test_an_imported_files_hints_are_bounded_like_a_request(properties: dict, named: str) -> None:
    path = mission_files.parse_document(_geojson(**properties))
    params = {"task_power_w": 1.0, **({} if "coa_radius_m" in properties else {"coa_radius_m": 2.0})}
    with pytest.raises(mission_files.PlanError, match=named):
        mission_files.mission_request(path, params, 1)


@pytest.mark.parametrize("properties, named", [
    ({"mission_id": {"x": 1}}, "mission_id"), ({"predict_disturbance": "yes"}, "predict_disturbance"),
    ({"coa_radius_m": "2"}, "coa_radius_m"), ({"task_power_w": True}, "task_power_w"),
    ({"speed_hint_mps": float("inf")}, "speed_hint_mps")])  # what JSON's 1e400 reads as
def test_a_geojson_hint_of_the_wrong_json_type_is_refused_not_converted(properties, named) -> None:
    """MissionRequest would turn "yes" into True and an object into a mission id's text."""
    with pytest.raises(mission_files.PlanError, match=named):
        mission_files.parse_document(_geojson(**properties))


def test_plan_numbers_past_a_floats_range_and_deep_nesting_are_plan_errors() -> None:
    doc = mission_export.to_plan([(47.0, 8.0), (47.001, 8.0)])
    for radius in (10**400, float("inf"), "2", True):  # 401 digits, what JSON's 1e400 reads as
        doc["mission"]["items"][0]["params"][1] = radius
        with pytest.raises(mission_files.PlanError, match=r"items\[0\].*acceptance radius params\[1\]"):
            mission_files.parse_document(doc)
    doc["mission"]["items"][0]["params"][1] = None  # QGroundControl's NaN: the default, no hint
    assert mission_files.parse_document(doc).hints.get("coa_radius_m") is None
    doc["mission"]["items"][0]["params"][4] = 10**400  # a latitude
    with pytest.raises(mission_files.PlanError, match="latitude"):
        mission_files.parse_document(doc)
    with pytest.raises(mission_files.PlanError, match="nested too deeply"):
        mission_files.load_json("[" * 100_000 + "]" * 100_000)
    with pytest.raises(mission_files.PlanError, match="a number too long to read"):
        mission_files.load_json('{"a": 1' + "0" * 5000 + "}")
