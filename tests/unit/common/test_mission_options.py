"""A mission's options: the request's ``predict_disturbance``, MissionSpec's overrides, scenario files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
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
