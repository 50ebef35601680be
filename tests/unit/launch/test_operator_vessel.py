"""Which vessel the operator commands speak to in a fleet, ``echo --vessel '*'``'s lines, and the
launcher's report of a vessel that flew no mission (issue #56 item 11). Pure parts here; the
commands against a running fleet are in tests/system/launch/test_fleet_operator_cli.py."""

from __future__ import annotations

from seaway.contract import keys
from seaway.contract.messages import ThrustCommand
from seaway.runtime.service import DEFAULT_VESSEL
from seaway.tools import cli, vessel_choice
from seaway.tools.launch import final_report as launch


def test_a_named_vessel_is_taken_one_running_is_found_several_are_asked_about() -> None:
    assert vessel_choice.choose("boat2", ["va", "vb"]) == ("boat2", None)
    assert vessel_choice.choose(None, ["boat1"]) == ("boat1", None)  # not the default's name
    assert vessel_choice.choose(None, []) == (DEFAULT_VESSEL, None)  # then: nothing answers
    vessel, problem = vessel_choice.choose(None, ["vb", "va"])
    assert vessel is None and "va, vb" in problem and "--vessel" in problem


def test_echo_of_every_vessel_says_whose_each_line_is() -> None:
    import json

    msg = ThrustCommand(stamp_ns=1, thrust_port_n=1.0, thrust_starboard_n=2.0, source="x")
    one = cli.echo_line(keys.THRUST.key("vb"), msg, every=False)
    assert json.loads(one) == json.loads(msg.model_dump_json())  # one vessel: the message as it is
    line = json.loads(cli.echo_line(keys.THRUST.key("vb"), msg, every=True))
    assert line["vessel"] == "vb" and line["message"] == json.loads(msg.model_dump_json())


def test_a_vessel_that_flew_no_mission_gets_no_report(tmp_path, capsys, monkeypatch) -> None:
    """A fleet's vessel the operator never sent a mission got a report against the scenario's
    path (34,775 J 'used' on a lake path it was never sent): there is none now, and it is said."""
    ran: list[list[str]] = []

    def popen(cmd: list[str], **_kw: object) -> None:
        ran.append(cmd)
        raise OSError("the report is not run in this test")

    monkeypatch.setattr(launch.subprocess, "Popen", popen)
    (tmp_path / "recording.mcap").write_bytes(b"")
    launch._final_report(tmp_path, "lake", None, idle_vessel="vessel2")
    assert "no report: vessel vessel2 flew no mission" in capsys.readouterr().out and not ran
    launch._final_report(tmp_path, "lake", None)  # it flew one: the report is made as before
    assert ran and "no report: vessel" not in capsys.readouterr().out
