"""``seaway mission SCENARIO`` checks the scenario it reads whole, as the simulator loads it (its
tables, its model and plant vessel files), before sending anything, and says what of it is not
sent: only ``[mission]`` goes to the controller. The transport (``request_cli.send``) is replaced
by a recorder of what would be sent: these are tests of what is read."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from seaway.contract.config import deploy_path
from seaway.tools import mission_cli, request_cli

VESSELS = deploy_path("vessels", "paper-boat.toml").parent


@pytest.fixture
def sent(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    out: list[Any] = []

    def send(_args: Any, _spec: Any, request: Any, _what: str) -> int:
        out.append(request)
        return 0

    monkeypatch.setattr(request_cli, "send", send)
    return out


def scenario_file(tmp_path: Path, vessel: str, plant: str | None = None) -> Path:
    path = tmp_path / "probe.toml"
    path.write_text(
        f'name = "probe"\nseed = 3\nvessel = "{vessel}"\n'
        + (f'plant_vessel = "{plant}"\n' if plant else "")
        + '[[disturbances]]\nkind = "current"\nnorth_mps = 0.1\neast_mps = 0.0\n'
        + "[mission]\nwaypoints_m = [[0.0, 0.0], [10.0, 0.0]]\ncoa_radius_m = 1.0\ntask_power_w = 5.0\n"
    )
    return path


def bad_vessel(tmp_path: Path) -> Path:
    text = (VESSELS / "paper-boat.toml").read_text()
    assert "m11_kg = 12.84" in text
    path = tmp_path / "heavy-negative.toml"
    path.write_text(text.replace("m11_kg = 12.84", "m11_kg = -12.84"))
    return path


@pytest.mark.parametrize("role", ["model", "plant"])
def test_a_scenario_whose_vessel_file_is_invalid_is_refused_naming_it(
    tmp_path: Path, sent: list[Any], capsys: pytest.CaptureFixture[str], role: str
) -> None:
    bad = bad_vessel(tmp_path)
    path = (
        scenario_file(tmp_path, str(bad))
        if role == "model"
        else scenario_file(tmp_path, "paper-boat", plant=str(bad))
    )
    assert mission_cli.main([str(path)]) == request_cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert "probe" in err and f"{role} vessel file" in err and "m11_kg" in err, err
    assert sent == []  # nothing went to the controller


def test_a_valid_scenario_sends_its_mission_and_says_what_it_ignored(
    tmp_path: Path, sent: list[Any], capsys: pytest.CaptureFixture[str]
) -> None:
    path = scenario_file(tmp_path, "paper-boat")
    assert mission_cli.main([str(path)]) == 0
    (req,) = sent
    assert req.mission_id == "probe" and len(req.waypoints) == 2
    err = capsys.readouterr().err
    assert "only [mission]" in err and "disturbances" in err and "vessel" in err, err
    assert "mission" not in err.split("are not sent")[0].split("its ")[-1]


def test_a_named_scenario_is_checked_and_a_mission_file_has_no_note(
    sent: list[Any], capsys: pytest.CaptureFixture[str]
) -> None:
    assert mission_cli.main(["lake"]) == 0
    assert "disturbances" in capsys.readouterr().err
    assert mission_cli.main([str(deploy_path("missions", "lake-square.toml"))]) == 0
    assert capsys.readouterr().err == ""
    assert [r.mission_id for r in sent] == ["lake", "lake-square"]
