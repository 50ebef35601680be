"""The sim keeps each scenario loaded over the bus (``--state-file``, ``seaway_sim.kept``), so a
sim the launcher restarts flies the water it was given, not the run's. Pure file handling and the
scenario handler on the in-memory bus; the restart itself: tests/system/sim and the shared study
stack (tests/system/study/test_study_shared.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from seaway.contract.messages import ScenarioRequest
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel
from seaway_sim import kept
from seaway_sim.core import SimCore
from seaway_sim.node import SimNode
from seaway_sim.world import world_of


def app_with(state_file: Path | None) -> SimNode:
    sc = load_scenario("paper-c1")
    return SimNode(SimCore(sc, load_vessel(sc.vessel)), lockstep=True,
                  state_file=state_file)


def document(name: str) -> dict:
    return load_scenario(name).model_dump(mode="json", exclude_none=True)


def load(app: SimNode, doc: dict) -> tuple[bool, str]:
    reply = app.handle_scenario(ScenarioRequest(stamp_ns=0, action="load", scenario=doc))
    return reply.accepted, reply.reason


def test_a_loaded_scenario_is_kept_and_flies_again_from_the_file(tmp_path: Path) -> None:
    path = tmp_path / "run" / "sim-state.json"
    app = app_with(path)
    assert kept.load(path) is None  # nothing loaded yet: the run's scenario
    doc = document("paper-c5")
    accepted, why = load(app, doc)
    assert accepted, why
    saved = kept.load(path)
    assert saved is not None and saved.name == "paper-c5" and saved.document == doc
    # What a restarted sim builds from it is what the load flew.
    scenario, vessel, model = world_of(saved.document, str(path), None)
    assert scenario == app.core.scenario and vessel == app.core.vessel and model == app.model
    # A restart of the current scenario changes nothing kept; a refused load neither.
    app.handle_scenario(ScenarioRequest(stamp_ns=0, action="restart"))
    bad = document("paper-c2")
    bad["battery"] = {"initial_energy_j": 1e9}
    accepted, why = load(app, bad)
    assert not accepted and "initial_energy_j" in why
    assert kept.load(path) == saved
    # The next load replaces it.
    assert load(app, document("paper-c3"))[0]
    again = kept.load(path)
    assert again is not None and again.name == "paper-c3"
    assert not list(path.parent.glob(".sim-state.json.*"))  # no temporary file left


def test_a_load_that_cannot_be_kept_still_flies_and_the_reply_says_so(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    app = app_with(blocker / "sim-state.json")
    accepted, why = load(app, document("paper-c5"))
    assert accepted and app.core.scenario.name == "paper-c5"
    assert "not kept for a restart" in why and "not-a-folder" in why, why


def test_without_a_state_file_nothing_is_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                                  ) -> None:
    monkeypatch.chdir(tmp_path)
    assert load(app_with(None), document("paper-c5"))[0]
    assert list(tmp_path.iterdir()) == []


def test_a_file_that_cannot_be_used_is_refused_naming_it_and_what_is_wrong(tmp_path: Path) -> None:
    path = tmp_path / "sim-state.json"
    path.write_text("{not json")
    with pytest.raises(kept.KeptError, match=r"sim-state\.json"):
        kept.load(path)
    path.write_text(json.dumps({"name": "x", "saved_unix_ns": 1}))
    with pytest.raises(kept.KeptError, match=r"document: Field required"):
        kept.load(path)
    path.write_text(json.dumps({"name": "x", "document": {}, "saved_unix_ns": -1, "extra": 1}))
    with pytest.raises(kept.KeptError) as err:
        kept.load(path)
    assert "saved_unix_ns" in str(err.value) and "extra: unknown field" in str(err.value)
    folder = tmp_path / "a-folder"
    folder.mkdir()
    with pytest.raises(kept.KeptError, match="cannot read it"):
        kept.load(folder)
