"""The replay view's missions: the controller's recorded ``mission/accepted`` first, and a fleet
vessel's recording finds the ground station's journal in the run folder above it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from seaway.contract import keys
from seaway.contract.messages import MissionAccepted, MissionRequest, Waypoint
from seaway.runtime.memory_bus import MemoryHub
from seaway_groundstation.app import create_app
from seaway_groundstation.journal import RequestJournal
from seaway_groundstation.settings import Settings
from seaway_recorder.core import RecordingWriter

from tests.unit.groundstation.test_gs_replay import PERIOD_NS, T0, TOKEN, V, write_run


@pytest.fixture
def runs(tmp_path: Path) -> Path:
    return tmp_path / "runs"


@pytest.fixture
def client(runs: Path, tmp_path: Path) -> Iterator[TestClient]:
    settings = Settings(token=TOKEN, runs_dir=runs, upload_dir=tmp_path / "uploads",
                        max_upload_bytes=200_000)
    with TestClient(create_app(MemoryHub().bus("gs"), settings)) as c:
        yield c


def sent(mission_id: str, east_m: float) -> MissionRequest:
    return MissionRequest(stamp_ns=T0, mission_id=mission_id, coa_radius_m=1.5, task_power_w=10.0,
                          waypoints=[Waypoint(x_m=0.0, y_m=east_m), Waypoint(x_m=20.0, y_m=east_m)])


def add_accepted(run: Path, msgs: list[MissionAccepted]) -> None:
    """A second recording file in the run folder holding the controller's acceptances."""
    w = RecordingWriter(run / "recording-accepted.mcap", foxglove=False)
    w.open(T0)
    for m in msgs:
        assert w.write(keys.MISSION_ACCEPTED.key(V), m.encode(), f"application/json;{m.SCHEMA}",
                       m.stamp_ns)
    w.close(T0 + 60 * PERIOD_NS)


def accepted(mission_id: str, east_m: float, k: int) -> MissionAccepted:
    return MissionAccepted(stamp_ns=T0 + k * PERIOD_NS, accepted_ns=T0 + k * PERIOD_NS,
                           mission_id=mission_id, coa_radius_m=2.5, task_power_w=3.0,
                           waypoints=[Waypoint(x_m=0.0, y_m=east_m), Waypoint(x_m=9.0, y_m=east_m)],
                           controller="nmpc", predict_disturbance=True)


def test_the_recorded_acceptance_wins_over_the_journal(client: TestClient, runs: Path) -> None:
    run = write_run(runs / "r1", n=50, mission_id="m1")
    RequestJournal(run).record(V, keys.MISSION_SET.suffix, "accepted", "ok",
                               sent("m1", 0.5).model_dump(mode="json"))
    # m1 sent twice under one id (the last counts), and m2 known only from the recording.
    add_accepted(run, [accepted("m1", 4.0, 1), accepted("m1", 7.0, 20), accepted("m2", 1.0, 30)])
    d = client.get("/api/recording", params={"id": "r1"}).json()
    plans = {p["mission_id"]: p for p in d["missions"]}
    assert set(plans) == {"m1", "m2"}
    assert plans["m1"]["source"] == "recording"
    assert plans["m1"]["waypoints_m"] == [[0.0, 7.0], [9.0, 7.0]]
    assert (plans["m1"]["coa_radius_m"], plans["m1"]["controller"],
            plans["m1"]["predict_disturbance"]) == (2.5, "nmpc", True)
    assert plans["m2"]["waypoints_m"] == [[0.0, 1.0], [9.0, 1.0]]


def test_a_fleet_vessels_recording_reads_the_journal_of_its_run(client: TestClient, runs: Path) -> None:
    """``<run>/<vessel>/recording.mcap``: the fleet's one ground station journals in ``<run>``."""
    run = runs / "fleet-run"
    write_run(run / V, n=20, mission_id="gs-1")
    journal = RequestJournal(run)
    journal.record(V, keys.MISSION_SET.suffix, "accepted", "ok", sent("gs-1", 2.0).model_dump(mode="json"))
    journal.record("other", keys.MISSION_SET.suffix, "accepted", "ok",
                   sent("gs-2", 3.0).model_dump(mode="json"))
    d = client.get("/api/recording", params={"id": f"fleet-run/{V}"}).json()
    (plan,) = d["missions"]  # its own vessel's, not the other vessel's
    assert (plan["mission_id"], plan["source"]) == ("gs-1", "groundstation")
    assert plan["waypoints_m"] == [[0.0, 2.0], [20.0, 2.0]]
