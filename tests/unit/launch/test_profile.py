"""Launcher profiles: validation, one producer per key, start and stop order, back-off."""

from __future__ import annotations

import re

import pytest
from seaway.contract.config import ConfigError, parse_config
from seaway.tools.launch.profile import (
    BackoffPolicy,
    Profile,
    load_profile,
    start_order,
    stop_order,
    substitute,
)


def prof(*processes: dict) -> dict:
    return {"name": "t", "processes": list(processes)}


def p(name: str, service: str | None = None, **kw) -> dict:
    return {"name": name, "command": ["x"], "service": service, **kw}


def test_two_producers_of_one_key_refused() -> None:
    doc = prof(p("sim", "sim", produces=["sensors/gnss", "sim/truth"]), p("io", "vehicle_io"))
    with pytest.raises(ConfigError, match=r"key 'sensors/gnss' has two producers: 'sim' and 'io'"):
        parse_config(doc, Profile, "t.toml")


def test_default_producers_come_from_the_registry() -> None:
    profile = parse_config(prof(p("est", "estimator"), p("ctl", "controller")), Profile)
    assert "nav/state" in profile.processes[0].produced_keys()
    assert "ctrl/thrust" in profile.processes[1].produced_keys()
    with pytest.raises(ConfigError, match="two producers"):
        parse_config(prof(p("est", "estimator"), p("est2", "estimator")), Profile)


def test_unregistered_key_unknown_service_and_typos_refused() -> None:
    with pytest.raises(ConfigError, match="unregistered key 'nav/stat'"):
        parse_config(prof(p("a", "sim", produces=["nav/stat"])), Profile)
    with pytest.raises(ConfigError, match="service 'estimater' unknown"):
        parse_config(prof(p("a", "estimater")), Profile)
    with pytest.raises(ConfigError, match="restrat: unknown field"):
        parse_config(prof(p("a", restrat="never")), Profile)


def test_start_order_follows_after_and_cycles_are_refused() -> None:
    profile = parse_config(prof(p("c", after=["b"]), p("b", after=["a"]), p("a"), p("d")), Profile)
    assert [x.name for x in start_order(profile.processes)] == ["a", "b", "c", "d"]
    with pytest.raises(ConfigError, match="cycle: a -> b -> a"):
        parse_config(prof(p("a", after=["b"]), p("b", after=["a"])), Profile)
    with pytest.raises(ConfigError, match="unknown zz"):
        parse_config(prof(p("a", after=["zz"])), Profile)


def test_recorder_stops_last() -> None:
    profile = parse_config(prof(p("rec", "recorder"), p("sim", "sim", after=["rec"]),
                                p("ctl", "controller", after=["sim"])), Profile)
    assert [x.name for x in stop_order(profile.processes)] == ["ctl", "sim", "rec"]


def test_backoff_grows_and_caps() -> None:
    b = BackoffPolicy(initial_s=0.5, factor=2, max_s=3)
    assert [b.delay_s(k) for k in range(5)] == [0.5, 1.0, 2.0, 3.0, 3.0]


def test_backoff_never_overflows_and_its_fields_are_bounded() -> None:
    """factor ** n overflowed inside the supervisor (factor 1e200 at the third restart, the default
    2 at restart 1025), ending the run; such a factor passed --check."""
    assert BackoffPolicy().delay_s(5000) == 10.0
    widest = BackoffPolicy(initial_s=0.001, factor=10.0, max_s=3600.0, max_restarts=1000)
    assert [widest.delay_s(k) for k in (0, 1, 6, 7, 1000, 10**6)] == pytest.approx(
        [0.001, 0.01, 1000.0, 3600.0, 3600.0, 3600.0])
    assert BackoffPolicy(factor=1.0).delay_s(10**6) == 0.5
    for field, value, bound in (("factor", 1e200, "10"), ("max_restarts", 5000, "1000"),
                                ("max_s", 1e300, "3600"), ("initial_s", 1e-300, "0.001")):
        with pytest.raises(ConfigError, match=rf"backoff\.{field}: Input should be .* {bound}$"):
            parse_config({**prof(p("a")), "backoff": {field: value}}, Profile, "t.toml")


def test_placeholders() -> None:
    assert substitute(["--v", "{vessel}"], {"vessel": "b1"}) == ["--v", "b1"]
    assert substitute(["{{x}}={vessel}"], {"vessel": "b1"}) == ["{x}=b1"]  # literal braces
    with pytest.raises(ConfigError, match=r"unknown placeholder 'vesel'"):
        substitute(["{vesel}"], {"vessel": "b1"})


@pytest.mark.parametrize(("arg", "named"), [
    ("X={0}", r"uses unknown placeholder '0' \(a placeholder is a bare name"),  # was IndexError
    ("X=}", r": Single '\}' encountered"),  # was ValueError
    ("X={", r": .*a literal brace is written \{\{ or \}\}"),
    ("X={vessel.zz}", r"uses unknown placeholder 'vessel\.zz'"),  # was AttributeError
    ("X={vessel[9]}", r"uses unknown placeholder 'vessel\[9\]'"),  # was IndexError
    ("X={}", r"uses unknown placeholder ''"),  # was IndexError
    ("X={vessel!r}", r": placeholder 'vessel' has a format spec or conversion"),
    ("X={vessel:>99}", r": placeholder 'vessel' has a format spec or conversion"),
])
def test_a_placeholder_that_is_not_a_bare_known_name_is_a_config_error_naming_the_argument(
        arg: str, named: str) -> None:
    with pytest.raises(ConfigError, match=rf"^command argument '{re.escape(arg)}' ?{named}"):
        substitute(["--param", arg], {"vessel": "b1"})


def test_shipped_profiles_are_valid() -> None:
    from seaway.contract.config import deploy_path

    names = sorted(x.stem for x in deploy_path("profiles").glob("*.toml"))
    assert "sim" in names
    for name in names:
        assert load_profile(name).name == name


def _launch_args(*argv: str):
    from seaway.tools.launch.main import parser

    return parser().parse_args(["sim", "--vessel", "boat1", *argv])


def test_a_boat_run_needs_no_scenario_and_takes_the_first_fix_as_origin() -> None:
    from seaway.tools.launch.main import resolve_run
    from seaway.tools.launch.profile import load_profile

    boat = load_profile("boat")
    run = resolve_run(_launch_args(), boat, "", "r1")  # no scenario at all: a real boat
    assert (run.model_vessel_file, run.origin, run.scenario, run.clock) == ("paper-boat", None, None, "wall")
    # With the shipped stand-in simulator's scenario, the model and origin are still the boat's own.
    bench = resolve_run(_launch_args(), boat, boat.scenario or "", "r2")
    assert bench.model_vessel_file == "paper-boat" and bench.origin is None and bench.scenario == "lake"


def test_a_simulated_run_shares_the_scenario_frame_and_the_period_is_one_option() -> None:
    from seaway.tools.launch.main import resolve_run
    from seaway.tools.launch.profile import load_profile

    batch = load_profile("sim-batch")
    run = resolve_run(_launch_args("--control-period-s", "0.25"), batch, "paper-c4-perturbed", "r3")
    assert run.clock == "lockstep" and run.control_period_s == 0.25 and run.origin is not None
    assert (run.model_vessel_file, run.plant_vessel_file) == ("paper-sim", "paper-sim-perturbed")
    with pytest.raises(ConfigError, match="control_period_s"):  # a duration, but too long
        resolve_run(_launch_args("--control-period-s", "5"), batch, "paper-c1", "r4")
    with pytest.raises(SystemExit):  # no duration at all: refused by the parser
        _launch_args("--control-period-s", "-1")


def test_a_run_on_the_autopilots_own_sitl_has_the_identified_model_and_no_plant_of_ours() -> None:
    from seaway.tools.launch.main import resolve_run
    from seaway.tools.launch.profile import load_profile

    sitl = load_profile("sitl-ardupilot")
    run = resolve_run(_launch_args(), sitl, sitl.scenario or "", "r1")
    assert (run.model_vessel_file, run.plant_vessel_file, run.dead_zone) == (
        "ardupilot-sitl-motorboat", None, False)
    assert run.origin is not None and run.scenario == "lake"  # SITL's home is the lake's origin
    sim = resolve_run(_launch_args(), load_profile("sim"), "lake", "r2")
    assert sim.dead_zone and sim.model_vessel_file == "paper-boat"  # our simulator keeps both


def test_a_lockstep_member_must_be_required_in_a_lockstep_profile() -> None:
    """The clock waits for every member each period: an optional one that failed for good would
    hold simulated time for ever."""
    doc = {"name": "t", "clock": "lockstep",
           "processes": [p("sim", "sim"), p("rec", "recorder", required=False)]}
    with pytest.raises(ConfigError, match=r"'rec'.*lockstep member"):
        parse_config(doc, Profile, "t.toml")
    doc["clock"] = "wall"
    assert not parse_config(doc, Profile, "t.toml").processes[1].required


@pytest.mark.parametrize("name", ["sim", "boat", "sitl-px4", "sitl-ardupilot", "fleet", "shore"])
def test_a_real_time_run_does_not_end_with_its_recorder_and_a_batch_run_does(name: str) -> None:
    """A card gone read-only must not end a boat's control loop: in real time the run goes on
    unrecorded (and says so); in a batch run the recording is the point, and the clock waits for it."""
    (rec,) = [x for x in load_profile(name).processes if x.service == "recorder"]
    assert not rec.required
    for batch in ("sim-batch", "replay"):
        (rec,) = [x for x in load_profile(batch).processes if x.service == "recorder"]
        assert rec.required
