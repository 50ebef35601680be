"""The fleet view (vessels from health and messages, ages, the stream's latest-only frames) and the
request bounds (token bucket), with time passed in."""

from __future__ import annotations

import json
import math

import pytest
from seaway.contract.messages import MissionStatus, StateEstimate
from seaway_groundstation.fleet import Fleet
from seaway_groundstation.limits import RateLimiter


def state(x_m: float, stamp_ns: int = 0) -> StateEstimate:
    return StateEstimate(stamp_ns=stamp_ns, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x_m, y_m=0.0,
                         psi_rad=0.0)


def test_vessels_come_from_health_and_messages_not_from_the_ground_station_itself() -> None:
    fleet = Fleet(stale_after_s=2.0)
    fleet.on_health("gs-home", "groundstation", True, 0.0)
    assert fleet.vessels() == [] and not fleet.knows("gs-home")
    fleet.on_health("v1", "controller", True, 1.0)
    fleet.on_message("v2", "state", state(1.0), 1.0)
    assert fleet.vessels() == ["v1", "v2"]
    assert fleet.on_health("v1", "controller", True, 1.5) is False  # no change
    view = fleet.view("v1", 2.0)
    assert view is not None and view.services == ["controller"] and view.state is None
    assert not view.simulated and math.isclose(view.last_heard_age_s or 0, 1.0)


def test_ages_and_stale_flags_follow_the_receive_time() -> None:
    fleet = Fleet(stale_after_s=2.0)
    fleet.on_message("v1", "state", state(3.0), 10.0)
    fleet.on_message("v1", "mission", MissionStatus(stamp_ns=0, state="active", waypoint_count=4), 11.5)
    view = fleet.view("v1", 12.5)
    assert view is not None and view.state is not None and view.mission is not None
    assert view.state.stale and math.isclose(view.state.age_s, 2.5)
    assert not view.mission.stale and view.mission.message.state == "active"
    assert not view.stale  # heard 1 s ago
    assert fleet.view("v1", 20.0).stale  # type: ignore[union-attr]
    assert fleet.view("nobody", 0.0) is None
    assert [v.vessel for v in fleet.views(12.5).vessels] == ["v1"]


def test_stream_frames_carry_only_the_latest_and_only_what_changed() -> None:
    fleet = Fleet(stale_after_s=2.0)
    fleet.on_health("v1", "estimator", True, 0.0)
    seen: dict = {}
    first = [json.loads(f) for f in fleet.changes(seen, None, 0.0)]
    assert first == [{"vessel": "v1", "services": ["estimator"], "stale_after_s": 2.0, "updates": {}}]
    for k in range(500):  # a burst while the client was busy: it gets the last one, not 500
        fleet.on_message("v1", "state", state(float(k)), 1.0)
    frames = [json.loads(f) for f in fleet.changes(seen, None, 1.25)]
    assert len(frames) == 1
    update = frames[0]["updates"]["state"]
    assert update["message"]["x_m"] == 499.0 and update["age_s"] == 0.25 and update["stale"] is False
    assert fleet.changes(seen, None, 1.3) == []  # nothing new
    fleet.on_message("v2", "state", state(7.0), 2.0)
    assert fleet.changes(seen, frozenset({"v1"}), 2.0) == []  # not watched
    assert json.loads(fleet.changes(seen, None, 2.0)[0])["vessel"] == "v2"


def test_rate_limiter_gives_a_burst_then_the_sustained_rate_per_client() -> None:
    limiter = RateLimiter(rate_per_s=2.0, burst=3)
    assert [limiter.allow("a", 0.0) for _ in range(3)] == [0.0, 0.0, 0.0]
    assert math.isclose(limiter.allow("a", 0.0), 0.5)
    assert limiter.allow("b", 0.0) == 0.0  # another client has its own bucket
    assert limiter.allow("a", 0.5) == 0.0  # one token back after 1 / rate
    assert RateLimiter(0.0, 1).allow("c", 0.0) == 0.0
    never = RateLimiter(0.0, 1)
    never.allow("c", 0.0)
    assert math.isinf(never.allow("c", 1e9))


def test_rate_limiter_forgets_the_oldest_clients_beyond_its_bound() -> None:
    limiter = RateLimiter(rate_per_s=0.0, burst=1, max_clients=2)
    for client in ("a", "b", "c"):
        limiter.allow(client, 0.0)
    assert limiter.allow("a", 0.0) == 0.0  # "a" was forgotten: a full bucket again
    with pytest.raises(ValueError):
        RateLimiter(1.0, 0)
