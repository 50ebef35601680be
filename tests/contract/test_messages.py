"""Contract: every message type round-trips, validates against its generated schema, refuses NaN."""

from __future__ import annotations

import json
import math
import re
import typing

import jsonschema
import pytest
from pydantic import BaseModel
from seaway.contract import messages as m
from seaway.contract.config import ConfigError, parse_config
from seaway.contract.messages import ALL_MESSAGES, MessageError
from seaway.vessel.model import VesselParams

T = 1_700_000_000_000_000_000

EXAMPLES: dict[type[m.Message], dict] = {
    m.GnssFix: dict(lat_rad=0.82, lon_rad=0.14, alt_m=3.0, fix_type=3, vel_n_mps=0.5, vel_e_mps=-0.1,
                    horizontal_std_m=0.3, satellites=12),
    m.Attitude: dict(roll_rad=0.01, pitch_rad=-0.02, yaw_rad=1.5, roll_rate_radps=0.0,
                     pitch_rate_radps=0.0, yaw_rate_radps=0.1),
    m.LocalPosition: dict(x_m=1.0, y_m=2.0, z_m=0.0, vx_mps=0.5, vy_mps=0.0, vz_mps=0.0),
    m.VehicleStatus: dict(autopilot="px4", link_ok=True, armed=False, mode="MANUAL", failsafe=None,
                          battery_voltage_v=12.4, battery_remaining_frac=0.8, heartbeat_age_s=0.2,
                          rates_hz={"ATTITUDE": 20.0}, dropped_messages=1),
    m.NavOrigin: dict(lat_rad=0.82, lon_rad=0.14, alt_m=0.0),
    m.StateEstimate: dict(u_mps=0.5, v_mps=0.01, r_radps=0.02, x_m=3.0, y_m=-1.0, psi_rad=0.3,
                          tau_d_surge_n=0.01, covariance=[0.0] * 81, degraded=False),
    m.ThrustCommand: dict(thrust_port_n=1.5, thrust_starboard_n=-0.5, source="cc-empc", seq=4),
    m.SolveRecord: dict(controller="cc-empc", status="Solve_Succeeded", success=True, iterations=3,
                        solve_time_s=0.0003, cost_stage_j=0.4, cost_dynamic_j=1.0, cost_static_j=30.0,
                        cost_track_j=0.2, t_d_s=2.0, t_s_s=100.0, leg_energy_to_go_j=31.0,
                        cross_track_m=0.1, predicted_x_m=[0.0, 0.1], predicted_y_m=[0.0, 0.0],
                        predicted_psi_rad=[0.0, 0.0], predicted_thrust_port_n=[1.0],
                        predicted_thrust_starboard_n=[1.0]),
    m.MissionStatus: dict(state="active", mission_id="m1", active_leg=1, waypoint_count=3,
                          distance_to_waypoint_m=4.0, cross_track_m=0.2, energy_used_j=10.0),
    m.SimTruth: dict(u_mps=0.5, v_mps=0.0, r_radps=0.0, x_m=1.0, y_m=0.0, psi_rad=0.0,
                     thrust_port_n=1.0, thrust_starboard_n=1.0, energy_j=3.0),
    m.DisturbanceForce: dict(surge_n=0.015, sway_n=0.015, yaw_nm=0.0),
    m.ClockTick: dict(lockstep=True, real_time_factor=250.0),
    m.PeriodDone: dict(service="recorder", episode=1, seq=7, period_ns=100_000_000,
                       published={"nav/state": [T]}, consumed={"ctrl/thrust": [T]},
                       covers={"sim": 3, "estimator": 4}, members=["estimator", "recorder"]),
    m.Reply: dict(accepted=False, reason="no", detail={"field": "x"}),
    m.ArmRequest: dict(arm=True),
    m.ModeRequest: dict(mode="MANUAL"),
    m.ScenarioRequest: dict(action="load", scenario={"name": "x"}),
    m.MissionRequest: dict(waypoints=[{"x_m": 0.0, "y_m": 0.0}, {"lat_deg": 47.0, "lon_deg": 8.0}],
                           coa_radius_m=1.0, task_power_w=0.49, controller="eo-empc"),
    m.MissionCommand: dict(command="pause"),
    m.HomeRequest: dict(home="here"),
    m.MissionAccepted: dict(accepted_ns=T, mission_id="m1", coa_radius_m=1.0, task_power_w=0.49,
                            waypoints=[{"x_m": 0.0, "y_m": 0.0}, {"x_m": 8.0, "y_m": 0.0}],
                            controller="cc-empc", predict_disturbance=False,
                            controller_settings={"horizon_steps": 10.0, "dt_s": 0.1}),
    m.BatteryState: dict(source="autopilot", voltage_v=15.2, current_a=3.1, power_w=47.1,
                         consumed_j=1200.0, remaining_j=400_000.0, remaining_frac=0.75,
                         capacity_j=532_800.0, reserve_j=106_560.0),
    m.EnergyBudget: dict(mission_id="m1", active_leg=1, energy_used_j=10.0, leg_energy_to_go_j=5.0,
                         energy_to_go_j=20.0, energy_to_go_low_j=18.0, energy_to_go_high_j=23.0,
                         energy_to_home_j=9.0, home_x_m=0.0, home_y_m=0.0,
                         battery_remaining_j=100.0, battery_stamp_ns=T, reserve_j=20.0,
                         margin_j=71.0, finish_margin_j=60.0, no_return_x_m=3.0,
                         no_return_y_m=1.0, no_return_along_m=4.0, policy="return",
                         decision="none"),
    m.NavResetRequest: dict(keep_origin=False, reason="operator"),
    m.LogRecord: dict(process="controller", level="INFO", logger="seaway_controller.core",
                      message="mission accepted"),
    m.ActiveArea: dict(since_ns=T, source="lake",
                       keep_in={"vertices": [{"x_m": -10.0, "y_m": -10.0}, {"x_m": 35.0, "y_m": -10.0},
                                             {"x_m": 35.0, "y_m": 30.0}, {"x_m": -10.0, "y_m": 30.0}]},
                       keep_out_circles=[{"name": "rock", "x_m": 11.0, "y_m": 9.0, "radius_m": 2.5}],
                       rally_points=[{"name": "jetty", "x_m": 0.0, "y_m": 0.0}]),
    m.Refusals: dict(identity="vehicle_io", total=3, overflow=0,
                     counts=[{"identity": "estimator", "action": "put", "key": "seaway/v1/ctrl/thrust",
                              "count": 3, "last_ns": 5}]),
}


def test_every_message_type_has_an_example() -> None:
    assert set(EXAMPLES) == set(ALL_MESSAGES)


def test_the_package_hands_on_every_public_name_of_its_modules() -> None:
    """A message, closed set or constant added to one of the package's modules is importable from
    ``seaway.contract.messages``, and every module is in ``MODULES`` (so its messages in
    ``ALL_MESSAGES``)."""
    import ast
    import inspect
    import pkgutil

    found = {info.name for info in pkgutil.iter_modules(m.__path__)}
    assert found == {module.__name__.rsplit(".", 1)[1] for module in m.MODULES}
    for module in m.MODULES:
        own = set()  # what the module itself defines at its top level
        for node in ast.parse(inspect.getsource(module)).body:
            if isinstance(node, ast.ClassDef | ast.FunctionDef):
                own.add(node.name)
            elif isinstance(node, ast.Assign | ast.AnnAssign):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                own |= {t.id for t in targets if isinstance(t, ast.Name)}
        own = {name for name in own if not name.startswith("_")}
        assert own <= set(m.__all__), f"{module.__name__}: not handed on: {sorted(own - set(m.__all__))}"
        for name in own:
            assert getattr(m, name) is getattr(module, name), f"{module.__name__}.{name}"
    messages = {v for module in m.MODULES for v in vars(module).values()
                if isinstance(v, type) and issubclass(v, m.Message) and "SCHEMA" in vars(v)}
    assert set(ALL_MESSAGES) == messages and len(ALL_MESSAGES) == len(messages)


@pytest.mark.parametrize("cls", ALL_MESSAGES, ids=lambda c: c.__name__)
def test_round_trip_and_schema(cls: type[m.Message]) -> None:
    msg = cls.make(stamp_ns=T, **EXAMPLES[cls])
    wire = msg.encode()
    assert cls.decode(wire) == msg
    schema = cls.json_schema()
    assert schema["title"] == cls.SCHEMA
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.Draft202012Validator(schema).validate(json.loads(wire))


def test_schema_names_are_versioned_and_unique() -> None:
    names = [c.SCHEMA for c in ALL_MESSAGES]
    assert len(set(names)) == len(names)
    for n in names:
        assert re.fullmatch(r"seaway\.v\d+\.[A-Z][A-Za-z]+", n), n


def test_schema_rejects_a_wrong_payload() -> None:
    validator = jsonschema.Draft202012Validator(m.ThrustCommand.json_schema())
    with pytest.raises(jsonschema.ValidationError):
        validator.validate({"stamp_ns": T, "thrust_port_n": "fast", "thrust_starboard_n": 1.0})


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_refused_naming_the_field(bad: float) -> None:
    with pytest.raises(MessageError, match=r"ThrustCommand\.thrust_starboard_n"):
        m.ThrustCommand.make(stamp_ns=T, thrust_port_n=1.0, thrust_starboard_n=bad)
    with pytest.raises(MessageError, match=r"SolveRecord\.predicted_x_m\.1"):
        m.SolveRecord.make(stamp_ns=T, **{**EXAMPLES[m.SolveRecord], "predicted_x_m": [0.0, bad]})


@pytest.mark.parametrize("cls", [m.GnssFix, m.NavOrigin])
@pytest.mark.parametrize("alt_m", [1e20, 1e300, -5000.0])
def test_an_altitude_no_fix_reports_is_refused_naming_it(cls, alt_m: float) -> None:
    """A first fix at 1e300 m, taken as the origin, left every later position at north = east = 0
    (1e20 m: rounded to 8 km steps); vehicle_io's own bound on GLOBAL_POSITION_INT is the same."""
    with pytest.raises(MessageError, match="alt_m"):
        cls.make(**{**EXAMPLES[cls], "stamp_ns": 1, "alt_m": alt_m})
    assert cls.make(**{**EXAMPLES[cls], "stamp_ns": 1, "alt_m": m.GNSS_ALT_MAX_M}).alt_m == 1e5


@pytest.mark.parametrize("stamp_ns", [2**63, 10**400])
def test_a_stamp_past_int64_is_refused_naming_it(stamp_ns: int) -> None:
    """Any JSON integer parses; a lockstep answer stamped 10^400 opened a duty the launcher
    later divided into an OverflowError, and ended the stack."""
    with pytest.raises(MessageError, match="stamp_ns"):
        m.PeriodDone.make(**{**EXAMPLES[m.PeriodDone], "stamp_ns": stamp_ns})
    with pytest.raises(MessageError, match="stamp_ns"):
        m.ThrustCommand.decode(b'{"stamp_ns": %d, "thrust_port_n": 0, "thrust_starboard_n": 0}'
                               % stamp_ns)
    assert m.ThrustCommand.make(stamp_ns=m.MAX_STAMP_NS, thrust_port_n=0.0,
                                thrust_starboard_n=0.0).stamp_ns == 2**63 - 1


def test_encode_refuses_non_finite_even_when_validation_was_skipped() -> None:
    sneaky = m.ThrustCommand.model_construct(stamp_ns=T, thrust_port_n=math.nan, thrust_starboard_n=1.0,
                                            source="", seq=0)
    with pytest.raises(MessageError, match=r"ThrustCommand\.thrust_port_n: not finite"):
        sneaky.encode()


def test_text_that_mentions_nan_is_not_refused() -> None:
    r = m.Reply.make(stamp_ns=T, accepted=False, reason="NaN input and Infinity refused")
    assert m.Reply.decode(r.encode()).reason == r.reason


def test_messages_are_immutable() -> None:
    msg = m.ThrustCommand.make(stamp_ns=T, thrust_port_n=1.0, thrust_starboard_n=1.0)
    with pytest.raises(Exception, match="frozen"):
        msg.thrust_port_n = math.nan  # type: ignore[misc]


def test_decode_tolerates_unknown_fields_and_names_missing_ones() -> None:
    newer = {"stamp_ns": T, "thrust_port_n": 1.0, "thrust_starboard_n": 2.0, "added_in_v2": [1, 2]}
    assert m.ThrustCommand.decode(json.dumps(newer)).thrust_starboard_n == 2.0
    with pytest.raises(MessageError, match=r"ThrustCommand\.thrust_port_n: Field required"):
        m.ThrustCommand.decode(b'{"stamp_ns": 1, "thrust_starboard_n": 2.0}')
    with pytest.raises(MessageError):
        m.ThrustCommand.decode(b"\xff not json")


def test_config_types_reject_unknown_fields() -> None:
    doc = dict(name="x", m11_kg=1, m22_kg=1, m33_kgm2=1, xu_kgps=1, yv_kgps=1, nr_kgm2ps=1, arm_m=0.1,
               alpha_w_per_n2=0.4, thrust_max_n=10, thrust_maxn=12)
    with pytest.raises(ConfigError, match=r"thrust_maxn: unknown field"):
        parse_config(doc, VesselParams, "vessel.toml")


UNIT_SUFFIXES = ("_m", "_mps", "_rad", "_radps", "_n", "_nm", "_w", "_j", "_s", "_ns", "_v", "_frac",
                 "_hz", "_deg", "_factor", "_a")
# Fields whose elements carry the units of other fields, or name their own (a dict's keys), as
# their docstring says.
MIXED_UNITS = {"covariance", "controller_settings"}


def _float_fields(cls: type[BaseModel]) -> list[str]:
    out = []
    for name, f in cls.model_fields.items():
        ann = f.annotation
        args = set(typing.get_args(ann)) | {ann}
        if float in args or list[float] in args:
            out.append(name)
    return out


@pytest.mark.parametrize("cls", [*ALL_MESSAGES, m.Waypoint], ids=lambda c: c.__name__)
def test_float_fields_name_their_unit(cls: type[BaseModel]) -> None:
    for name in set(_float_fields(cls)) - MIXED_UNITS:
        assert name.endswith(UNIT_SUFFIXES), f"{cls.__name__}.{name} does not end in a unit suffix"


def _unknowns_left_out(cls: type[m.Message]) -> dict:
    """The example with every field that may be unknown (default None) left unknown."""
    if cls is m.ScenarioRequest:  # its document is there exactly when the action loads one
        return dict(action="restart")
    return {k: v for k, v in EXAMPLES[cls].items() if cls.model_fields[k].default is not None}


@pytest.mark.parametrize("cls", ALL_MESSAGES, ids=lambda c: c.__name__)
def test_a_message_with_unknown_fields_is_valid_against_its_schema(cls: type[m.Message]) -> None:
    # Unknown is absent on the wire, never null: the schema names an optional field's type alone
    # (so Foxglove reads it), which a null would break.
    msg = cls.make(stamp_ns=T, **_unknowns_left_out(cls))
    wire = json.loads(msg.encode())
    assert None not in wire.values()
    assert cls.decode(msg.encode()) == msg
    jsonschema.Draft202012Validator(cls.json_schema()).validate(wire)
    jsonschema.Draft202012Validator(cls.json_schema()).validate(json.loads(
        cls.make(stamp_ns=T, **EXAMPLES[cls]).encode()))


@pytest.mark.parametrize("cls", ALL_MESSAGES, ids=lambda c: c.__name__)
def test_a_null_is_refused_by_the_schema_of_every_optional_field(cls: type[m.Message]) -> None:
    schema = cls.json_schema()
    validator = jsonschema.Draft202012Validator(schema)
    wire = json.loads(cls.make(stamp_ns=T, **EXAMPLES[cls]).encode())
    optional = [k for k, f in cls.model_fields.items() if f.default is None]
    for name in optional:
        with pytest.raises(jsonschema.ValidationError):
            validator.validate({**wire, name: None})


def test_every_field_that_may_be_unknown_defaults_to_it() -> None:
    # Otherwise it could not be left out on the wire (Message.encode) and still decode.
    assert {c.__name__: m.nullable_fields_without_default(c) for c in ALL_MESSAGES
            if m.nullable_fields_without_default(c)} == {}
    from seaway.tools.launch.events import ProcessEvent

    assert m.nullable_fields_without_default(ProcessEvent) == []


def test_nullable_fields_without_default_finds_them() -> None:
    class Inner(BaseModel):
        a: int | None

    class Outer(BaseModel):
        b: float | None = 1.0
        c: list[Inner] = []
        d: str | None = None

    assert m.nullable_fields_without_default(Outer) == ["Outer.b", "Outer.c.a"]
