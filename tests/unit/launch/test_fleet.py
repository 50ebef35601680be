"""A launch of several vessels (``profile.instances``, ``main.supervised``): which processes run,
under which names, in which order, with which vessel's placeholders; and what is refused."""

from __future__ import annotations

from pathlib import Path

import pytest
from seaway.contract.config import ConfigError, parse_config
from seaway.tools.launch.main import launch_vessels, parser, supervised
from seaway.tools.launch.profile import Profile, instances, load_profile, start_order, stop_order


def prof(*processes: dict, **fields) -> Profile:
    return parse_config({"name": "t", "processes": list(processes), **fields}, Profile)


def p(name: str, service: str | None = None, **kw) -> dict:
    return {"name": name, "command": ["x", "{vessel}"], "service": service, **kw}


def fleet_of_three() -> Profile:
    return prof(p("rec", "recorder", per_vessel=True), p("gs", "groundstation", after=["rec"]),
                p("sim", "sim", per_vessel=True, after=["rec"]),
                p("ctl", "controller", per_vessel=True, after=["sim", "gs"]),
                vessels=["a", "b", "c"])


def test_per_vessel_processes_run_once_per_vessel_and_the_others_once_on_the_first() -> None:
    plan = instances(fleet_of_three(), ["a", "b"])
    assert [(i.spec.name, i.vessel, i.per_vessel) for i in plan] == [
        ("rec-a", "a", True), ("rec-b", "b", True), ("gs", "a", False),
        ("sim-a", "a", True), ("sim-b", "b", True), ("ctl-a", "a", True), ("ctl-b", "b", True)]
    after = {i.spec.name: i.spec.after for i in plan}
    # A copy waits for its own vessel's copies; the process of the whole launch waits for all.
    assert after["sim-b"] == ["rec-b"] and after["ctl-a"] == ["sim-a", "gs"]
    assert after["gs"] == ["rec-a", "rec-b"]
    order = [s.name for s in start_order([i.spec for i in plan])]
    assert order.index("gs") > max(order.index("rec-a"), order.index("rec-b"))
    assert order.index("ctl-b") > order.index("sim-b") > order.index("rec-b")
    # Every recorder stops last.
    assert [s.name for s in stop_order([i.spec for i in plan])][-2:] == ["rec-b", "rec-a"]


def test_a_launch_of_one_vessel_keeps_the_profile_as_it_is() -> None:
    plan = instances(fleet_of_three(), ["solo"])
    assert [(i.spec.name, i.vessel, i.per_vessel) for i in plan] == [
        ("rec", "solo", False), ("gs", "solo", False), ("sim", "solo", False), ("ctl", "solo", False)]
    assert plan[3].spec.after == ["sim", "gs"]


def test_what_cannot_run_as_a_fleet_is_refused_naming_it() -> None:
    clash = prof(p("sim", "sim", per_vessel=True), p("sim-b", "estimator"))
    with pytest.raises(ConfigError, match="two processes would be named sim-b; rename"):
        instances(clash, ["a", "b"])
    with pytest.raises(ConfigError, match="vessels listed twice: a"):
        instances(fleet_of_three(), ["a", "b", "a"])
    with pytest.raises(ConfigError, match="vessel name 'a b' is not valid"):
        instances(fleet_of_three(), ["a b"])
    with pytest.raises(ConfigError, match="a lockstep run has one vessel"):
        prof(p("sim", "sim", per_vessel=True), clock="lockstep", vessels=["a", "b"])
    lockstep = prof(p("sim", "sim", per_vessel=True), clock="lockstep")
    assert len(instances(lockstep, ["a"])) == 1
    with pytest.raises(ConfigError, match="a lockstep run has one vessel"):
        instances(lockstep, ["a", "b"])
    stops = prof(p("rp", "sim", per_vessel=True), stop_after="rp", vessels=["a", "b"])
    with pytest.raises(ConfigError, match="stop_after names 'rp', which runs once per vessel"):
        instances(stops, ["a", "b"])


def test_vessel_options_fit_the_profile() -> None:
    fleet, sim = load_profile("fleet"), load_profile("sim")
    assert launch_vessels(parser().parse_args(["fleet"]), fleet) == fleet.vessels
    assert launch_vessels(parser().parse_args(["fleet", "--vessels", "x,y,z"]), fleet) == ["x", "y", "z"]
    assert launch_vessels(parser().parse_args(["sim", "--vessel", "boat9"]), sim) == ["boat9"]
    with pytest.raises(ConfigError, match="--vessel: profile fleet runs the vessels it lists"):
        launch_vessels(parser().parse_args(["fleet", "--vessel", "x"]), fleet)
    with pytest.raises(ConfigError, match="--vessels: profile sim runs one vessel"):
        launch_vessels(parser().parse_args(["sim", "--vessels", "x,y"]), sim)


def test_the_fleet_profile_gives_each_vessel_its_own_run_folder_recording_and_mavlink_port(
        tmp_path: Path) -> None:
    fleet = load_profile("fleet")
    vessels = ["v1", "v2", "v3"]
    procs = supervised(instances(fleet, vessels), vessels, tmp_path,
                       {"scenario": "lake", "run_dir": str(tmp_path), "profile": "fleet.toml",
                        "recording": "", "mavlink_key": "/k"})
    by_name = {sp.spec.name: sp for sp in procs}
    assert sorted(by_name) == sorted([f"{n}-{v}" for n in ("recorder", "sim", "vehicle_io",
                                                            "estimator", "controller")
                                      for v in vessels] + ["groundstation"])

    def arg(sp, flag: str) -> str:
        return sp.argv[sp.argv.index(flag) + 1]

    ports = set()
    for v in vessels:
        rec, sim, vio = by_name[f"recorder-{v}"], by_name[f"sim-{v}"], by_name[f"vehicle_io-{v}"]
        assert (rec.vessel, rec.vessel_dir) == (v, tmp_path / v)
        assert (arg(rec, "--vessels"), arg(rec, "--out")) == (v, str(tmp_path / v))
        assert arg(rec, "--events") == str(tmp_path / v / "events.jsonl")
        for sp in (rec, sim, vio, by_name[f"controller-{v}"]):
            assert arg(sp, "--vessel") == v and arg(sp, "--run") == str(tmp_path / v / "run.json")
        port = arg(sim, "--mavlink").removeprefix("udpin:127.0.0.1:")
        assert arg(vio, "--mavlink") == f"udpout:127.0.0.1:{port}"
        ports.add(port)
    assert len(ports) == len(vessels)  # each autopilot on its own port
    # Each simulated vessel starts in a slot of its own, not on top of another.
    assert [arg(by_name[f"sim-{v}"], "--start-slot") for v in vessels] == ["0", "1", "2"]
    gs = by_name["groundstation"]
    assert (gs.vessel, gs.vessel_dir) == ("v1", None)  # one for the launch, on its first vessel
    assert arg(gs, "--run-dir") == str(tmp_path) and arg(gs, "--run") == str(tmp_path / "v1" / "run.json")
