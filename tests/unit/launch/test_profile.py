"""Launcher profiles: validation, one producer per key, start and stop order, back-off."""

from __future__ import annotations

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


def test_placeholders() -> None:
    assert substitute(["--v", "{vessel}"], {"vessel": "b1"}) == ["--v", "b1"]
    with pytest.raises(ConfigError, match=r"unknown placeholder 'vesel'"):
        substitute(["{vesel}"], {"vessel": "b1"})


def test_shipped_profiles_are_valid() -> None:
    from seaway.contract.config import deploy_path

    names = sorted(x.stem for x in deploy_path("profiles").glob("*.toml"))
    assert "sim" in names
    for name in names:
        assert load_profile(name).name == name
