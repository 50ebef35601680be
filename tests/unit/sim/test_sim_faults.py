"""Scheduled faults (``[[faults]]``, ``seaway.simkit.faults``): parsed with bounds, and applied by the
sim's core to its sensors and plant at the scenario's time."""

from __future__ import annotations

import math
import re

import pytest
from seaway.contract.config import ConfigError
from seaway.simkit import faults as fl
from seaway.simkit import scenario as sc
from seaway.vessel.frames import GeoOrigin, wrap_pi
from seaway.vessel.model import load_vessel
from seaway_sim.core import SimCore

from tests.conftest import REPO

PERIOD_NS = 100_000_000
S = 1_000_000_000


def lake_doc(faults: list[dict]) -> dict:
    doc = sc.load_scenario("lake").model_dump(mode="json")
    return {**doc, "faults": faults}


def quiet_lake(faults: list[dict]) -> sc.Scenario:
    """The lake without noise, wind or current (so that a fault is all that differs)."""
    doc = lake_doc(faults)
    doc["disturbances"] = []
    doc["sensors"] = {"gnss_rate_hz": 5.0, "attitude_rate_hz": 20.0}
    return sc.parse_scenario(doc, "quiet-lake")


def fly(scenario: sc.Scenario, seconds: float, command=(30.0, 20.0)):
    """The core after ``seconds`` at a constant command; every fix (None in a dropout), attitude
    and truth taken period by period."""
    core = SimCore(scenario, load_vessel(scenario.vessel))
    first = core.take_samples()
    fixes, atts, truths = list(first.gnss), list(first.attitude), [core.truth()]
    for _ in range(round(seconds * S / PERIOD_NS)):
        core.advance(command, PERIOD_NS)
        got = core.take_samples()
        fixes += got.gnss
        atts += got.attitude
        truths.append(core.truth())
    return core, fixes, atts, truths


@pytest.mark.parametrize(
    ("fault", "field", "bound"),
    [
        ({"kind": "thruster", "time_s": 1, "thruster": "port", "factor": 1.5}, "factor", "1"),
        ({"kind": "thruster", "time_s": 1, "thruster": "port", "factor": -0.1}, "factor", "0"),
        ({"kind": "thruster", "time_s": 1, "thruster": "middle", "factor": 0.5}, "thruster", "starboard"),
        ({"kind": "heading_bias", "start_s": 1, "bias_rad": 4.0}, "bias_rad", f"{math.pi}"),
        ({"kind": "gnss_dropout", "start_s": -1, "duration_s": 2}, "start_s", "0"),
        ({"kind": "gnss_dropout", "start_s": 1, "duration_s": 0}, "duration_s", "0"),
        ({"kind": "gnss_dropout", "start_s": 1}, "duration_s", "required"),
        ({"kind": "gnss_dropout", "start_s": 1e9, "duration_s": 1}, "start_s", f"{fl.MAX_FAULT_TIME_S:g}"),
        (
            {"kind": "position_jump", "time_s": 1, "distance_m": 1e6, "direction_rad": 0},
            "distance_m",
            f"{fl.MAX_POSITION_JUMP_M:g}",
        ),
        (
            {"kind": "position_jump", "time_s": 1, "distance_m": 5, "direction_rad": 99},
            "direction_rad",
            "6.28",
        ),
        ({"kind": "fire", "time_s": 1}, "kind", "thruster"),
        ({"kind": "gnss_dropout", "start_s": 1, "duration_s": 2, "extra": 1}, "extra", ""),
    ],
)
def test_a_fault_out_of_bounds_is_refused_naming_the_field_and_what_is_allowed(fault, field, bound) -> None:
    with pytest.raises(ConfigError) as err:
        sc.parse_scenario(lake_doc([fault]), "probe.toml")
    text = str(err.value)
    assert "probe.toml" in text and "faults.0" in text and field in text and bound in text, text


def _jump(time_s: float, distance_m: float, duration_s: float | None = None) -> dict:
    out = {"kind": "position_jump", "time_s": time_s, "distance_m": distance_m, "direction_rad": 0.0}
    return out if duration_s is None else {**out, "duration_s": duration_s}


@pytest.mark.parametrize(("faults", "sum_m", "from_s"), [
    ([_jump(10, 600, 5), _jump(12, 600, 5)], 1200, 12),   # two offsets overlapping from 12 s
    ([_jump(10, 600, 5), _jump(14.9, 600)], 1200, 14.9),  # an outlier inside an offset
    ([_jump(10, 300)] * 4, 1200, 10),                     # four outliers on one fix
])
def test_jumps_that_act_together_may_add_up_to_what_one_may_be(faults, sum_m, from_s) -> None:
    """Each jump is bounded; before, any number of them acting on one fix added without bound (a
    thousand 1 km jumps put a fix 1,000 km off, past the poles from a high origin)."""
    with pytest.raises(ConfigError) as err:
        sc.parse_scenario(lake_doc(faults), "probe.toml")
    text = str(err.value)
    assert "probe.toml" in text and "position jumps" in text, text
    # The sum, when it first acts and the bound, as numbers with their units.
    for figure in (f"{sum_m:g} m", f"{from_s:g} s", f"{fl.MAX_POSITION_JUMP_M:g} m"):
        assert re.search(rf"(?<![\d.]){re.escape(figure)}\b", text), (figure, text)


def test_jumps_apart_in_time_are_each_bounded_alone() -> None:
    apart = [_jump(10, 600, 5), _jump(15, 600, 5), _jump(30, 900), _jump(31, 900)]
    assert len(sc.parse_scenario(lake_doc(apart), "probe.toml").faults) == 4
    assert fl.jump_peak(sc.parse_scenario(lake_doc(apart), "probe.toml").faults, 0.2) == (900.0, 30.0)


def test_a_scenario_without_faults_has_none_and_the_shipped_example_parses() -> None:
    assert sc.load_scenario("lake").faults == []
    example = sc.load_scenario("lake-faults")
    assert {f.kind for f in example.faults} == {"gnss_dropout", "position_jump", "heading_bias", "thruster"}
    assert (REPO / "deploy" / "scenarios" / "lake-faults.toml").is_file()


def test_a_gnss_dropout_removes_exactly_the_fixes_in_its_window_and_says_gnss_lost() -> None:
    scenario = quiet_lake([{"kind": "gnss_dropout", "start_s": 2.0, "duration_s": 1.5}])
    core = SimCore(scenario, load_vessel(scenario.vessel))
    lost, stamps, missing = {}, [], 0
    for k in range(1, 51):
        core.advance((30.0, 20.0), PERIOD_NS)
        lost[k * PERIOD_NS] = not core.gnss_ok()
        for fix in core.take_samples().gnss:
            if fix is None:
                missing += 1
            else:
                stamps.append(fix.stamp_ns)
    assert [t for t, v in lost.items() if v] == [t for t in lost if 2 * S <= t < 3.5 * S]
    assert not [t for t in stamps if 2 * S <= t < 3.5 * S]
    assert missing == round(1.5 * 5)  # 5 Hz: the fixes due at 2.0 ... 3.4 s
    assert stamps == [
        t for t in range(0, 5 * S + 1, PERIOD_NS * 2) if not 2 * S <= t < 3.5 * S
    ]  # t_0 at load


def test_a_position_jump_moves_one_fix_or_every_fix_in_its_window() -> None:
    origin = None
    _, clean, _, _ = fly(quiet_lake([]), 4.0)
    one = [{"kind": "position_jump", "time_s": 1.05, "distance_m": 20.0, "direction_rad": math.pi / 2}]
    window = [
        {
            "kind": "position_jump",
            "time_s": 2.0,
            "distance_m": 5.0,
            "direction_rad": math.pi,
            "duration_s": 1.0,
        }
    ]
    for faults, expected in (
        (one, {1.2: (0.0, 20.0)}),
        (window, {t / 5: (-5.0, 0.0) for t in range(10, 15)}),
    ):
        core, fixes, _, _ = fly(quiet_lake(faults), 4.0)
        origin = GeoOrigin(core.origin.lat_rad, core.origin.lon_rad, core.origin.alt_m)
        for a, b in zip(clean, fixes, strict=True):
            na, ea, _ = origin.to_ned(a.lat_rad, a.lon_rad, a.alt_m)
            nb, eb, _ = origin.to_ned(b.lat_rad, b.lon_rad, b.alt_m)
            dn, de = expected.get(round(a.stamp_ns / S, 3), (0.0, 0.0))
            assert nb - na == pytest.approx(dn, abs=1e-6) and eb - ea == pytest.approx(de, abs=1e-6), (
                a.stamp_ns
            )
            assert (b.vel_n_mps, b.vel_e_mps) == (a.vel_n_mps, a.vel_e_mps)  # the velocity is not moved


def test_a_heading_bias_is_added_while_it_lasts() -> None:
    bias = [{"kind": "heading_bias", "start_s": 1.0, "bias_rad": 0.2, "duration_s": 1.0}]
    _, _, clean, _ = fly(quiet_lake([]), 3.0)
    _, _, biased, _ = fly(quiet_lake(bias), 3.0)
    for a, b in zip(clean, biased, strict=True):
        expected = 0.2 if S <= a.stamp_ns < 2 * S else 0.0
        assert wrap_pi(b.yaw_rad - a.yaw_rad) == pytest.approx(expected, abs=1e-12), a.stamp_ns
        assert b.yaw_rate_radps == a.yaw_rate_radps


@pytest.mark.parametrize(
    ("thruster", "factor", "expected"),
    [
        ("port", 0.0, (0.0, 20.0)),
        ("starboard", 0.5, (30.0, 10.0)),
        ("both", 0.25, (7.5, 5.0)),
    ],
)
def test_a_thruster_fault_scales_what_it_produces_and_changes_the_trajectory_from_then(
    thruster, factor, expected
) -> None:
    fault = [{"kind": "thruster", "time_s": 2.0, "thruster": thruster, "factor": factor}]
    _, _, _, clean = fly(quiet_lake([]), 4.0)
    _, _, _, faulty = fly(quiet_lake(fault), 4.0)
    for a, b in zip(clean, faulty, strict=True):
        if a.stamp_ns <= 2 * S:
            assert a == b  # the same run, bit for bit, until the fault
        else:
            assert (b.thrust_port_n, b.thrust_starboard_n) == pytest.approx(expected)
    assert math.hypot(clean[-1].x_m - faulty[-1].x_m, clean[-1].y_m - faulty[-1].y_m) > 0.1
    assert faulty[-1].energy_j < clean[-1].energy_j  # counts the thrust produced


def test_a_thruster_fault_with_a_duration_ends_and_faults_of_one_kind_combine() -> None:
    faults = [
        {"kind": "thruster", "time_s": 1.0, "thruster": "port", "factor": 0.5, "duration_s": 1.0},
        {"kind": "thruster", "time_s": 1.5, "thruster": "both", "factor": 0.5, "duration_s": 1.0},
    ]
    _, _, _, truths = fly(quiet_lake(faults), 3.0)
    by_t = {round(t.stamp_ns / S, 1): (t.thrust_port_n, t.thrust_starboard_n) for t in truths}
    assert by_t[1.0] == (30.0, 20.0)  # the step ending at 1.0 s was taken before the fault
    assert by_t[1.2] == (15.0, 20.0)
    assert by_t[1.8] == (7.5, 10.0)
    assert by_t[2.2] == (30.0 * 0.5, 10.0)
    assert by_t[2.8] == (30.0, 20.0)


def test_faults_are_timed_from_the_scenario_start_after_a_reload() -> None:
    scenario = quiet_lake([{"kind": "gnss_dropout", "start_s": 1.0, "duration_s": 1.0}])
    core = SimCore(quiet_lake([]), load_vessel(scenario.vessel))
    for _ in range(30):  # 3 s of another scenario
        core.advance((0.0, 0.0), PERIOD_NS)
    core.load(scenario, load_vessel(scenario.vessel))  # time goes on: t = 3 s
    core.take_samples()
    stamps = []
    for _ in range(30):
        core.advance((0.0, 0.0), PERIOD_NS)
        stamps += [f.stamp_ns if f is not None else None for f in core.take_samples().gnss]
    assert stamps.count(None) == 5 and stamps[4:9] == [None] * 5  # 4.0 ... 4.8 s of sim time


def test_lockstep_cores_with_faults_stay_deterministic() -> None:
    example = sc.load_scenario(REPO / "deploy" / "scenarios" / "lake-faults.toml")
    runs = [fly(example, 6.0) for _ in range(2)]
    assert [t.encode() for t in runs[0][3]] == [t.encode() for t in runs[1][3]]
    assert [None if f is None else f.encode() for f in runs[0][1]] == [
        None if f is None else f.encode() for f in runs[1][1]
    ]


def test_a_stuck_thruster_gives_its_thrust_whatever_is_commanded() -> None:
    fault = [{"kind": "stuck_thruster", "time_s": 2.0, "thruster": "port", "thrust_n": 0.0}]
    _, _, _, truths = fly(quiet_lake(fault), 4.0)
    before = [t for t in truths if 0 < t.stamp_ns <= 2 * S]
    after = [t for t in truths if t.stamp_ns > 2 * S]
    assert all((t.thrust_port_n, t.thrust_starboard_n) == (30.0, 20.0) for t in before)
    assert all((t.thrust_port_n, t.thrust_starboard_n) == (0.0, 20.0) for t in after)
    stuck_at = [{"kind": "stuck_thruster", "time_s": 1.0, "thruster": "both", "thrust_n": 15.0,
                 "duration_s": 1.0}]
    _, _, _, truths = fly(quiet_lake(stuck_at), 3.0)
    by_t = {round(t.stamp_ns / S, 1): (t.thrust_port_n, t.thrust_starboard_n) for t in truths}
    assert by_t[1.5] == (15.0, 15.0) and by_t[2.5] == (30.0, 20.0)


def test_a_grounding_holds_the_vessel_where_it_is_whatever_the_thrust() -> None:
    fault = [{"kind": "grounding", "time_s": 2.0, "duration_s": 2.0}]
    _, _, _, truths = fly(quiet_lake(fault), 6.0)
    by_t = {round(t.stamp_ns / S, 1): t for t in truths}
    assert by_t[1.9].u_mps > 0.3
    held = [by_t[k / 10] for k in range(21, 41)]
    assert all((t.u_mps, t.v_mps, t.r_radps) == (0.0, 0.0, 0.0) for t in held)
    assert len({(t.x_m, t.y_m, t.psi_rad) for t in held}) == 1
    assert by_t[6.0].u_mps > 0.3  # afloat again


@pytest.mark.parametrize(("fault", "field", "bound"), [
    ({"kind": "stuck_thruster", "time_s": 1, "thruster": "aft", "thrust_n": 1}, "thruster", "starboard"),
    ({"kind": "stuck_thruster", "time_s": 1, "thruster": "port"}, "thrust_n", "required"),
    ({"kind": "stuck_thruster", "time_s": 1, "thruster": "port", "thrust_n": 1e6}, "thrust_n", "10000"),
    ({"kind": "grounding", "time_s": -1}, "time_s", "0"),
    ({"kind": "grounding", "time_s": 1, "duration_s": 0}, "duration_s", "0"),
])
def test_a_stuck_thruster_or_grounding_out_of_bounds_is_refused(fault, field, bound) -> None:
    with pytest.raises(ConfigError) as err:
        sc.parse_scenario(lake_doc([fault]), "probe.toml")
    text = str(err.value)
    assert "probe.toml" in text and "faults.0" in text and field in text and bound in text, text


def test_a_stuck_thrust_beyond_what_the_vessel_gives_is_refused_naming_the_range() -> None:
    scenario = quiet_lake([{"kind": "stuck_thruster", "time_s": 1, "thruster": "port", "thrust_n": 80.0}])
    with pytest.raises(ConfigError, match=r"faults\.0\.thrust_n = 80 N.*to 75 N"):
        SimCore(scenario, load_vessel(scenario.vessel))
