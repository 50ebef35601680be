"""``seaway report`` reports the missions actually flown, not the scenario's (issue 14, item 5).

A run of the lake scenario in which the operator sent another mission to the live stack used to be
reported against the scenario's mission ("completed NO, XTE 13.6 m, 159 kJ"). The report now takes
the missions from the controller's recorded statuses, uses a document for one only if it fits what
the controller reported while flying it, and says so when the waypoints flown are not known.

The recordings are written here with the real writer: a boat sailing north along x at 1 m/s, the
controller's statuses for the mission it flew, and the lake scenario attached as a launch does.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    MissionAccepted,
    MissionRequest,
    MissionStatus,
    SimTruth,
    StateEstimate,
    Waypoint,
)
from seaway.recording import runinfo
from seaway_recorder import attachments, missions, report
from seaway_recorder.core import RecordingWriter

V = "vessel1"
DT_NS = 100_000_000
PROBE = [(0.0, 0.0), (20.0, 0.0)]  # the mission flown: 20 m north (not the lake's 62 m box)


def status(k: int, mission_id: str, wps: list[tuple[float, float]], x: float,
           state: str = "active") -> MissionStatus:
    return MissionStatus.make(stamp_ns=k * DT_NS, state=state, mission_id=mission_id, active_leg=1,
                              waypoint_count=len(wps), energy_used_j=1.0 * k,
                              distance_to_waypoint_m=math.dist((x, 0.0), wps[1]),
                              cross_track_m=0.0)


def accepted(k: int, mission_id: str, wps: list[tuple[float, float]], accepted_k: int | None = None,
             task_power_w: float = 250.0) -> MissionAccepted:
    """The controller's ``mission/accepted`` published at period k (accepted at ``accepted_k``)."""
    return MissionAccepted.make(stamp_ns=k * DT_NS, accepted_ns=(k if accepted_k is None else
                                                                 accepted_k) * DT_NS,
                                mission_id=mission_id, coa_radius_m=1.0, task_power_w=task_power_w,
                                waypoints=[Waypoint(x_m=x, y_m=y) for x, y in wps],
                                controller="eo-empc", predict_disturbance=False)


def write(path: Path, flights: list[tuple[str, list[tuple[float, float]], int]],
          announced: list[MissionAccepted] = ()) -> Path:
    """One episode: each flight (mission id, waypoints, periods) after the other, the boat at
    1 m/s north, restarting from x = 0 for each; the controller's status every period; each of
    ``announced`` (``mission/accepted``) at its stamp, before that period's status."""
    atts, _ = attachments.scenario_attachments("lake")
    w = RecordingWriter(path, attachments=atts, foxglove=False)
    w.open(0)
    k = 0
    for mission_id, wps, periods in flights:
        for i in range(periods):
            x = 0.1 * i
            t = k * DT_NS
            w.write(keys.SIM_TRUTH.key(V), SimTruth.make(
                stamp_ns=t, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x, y_m=0.0, psi_rad=0.0,
                thrust_port_n=10.0, thrust_starboard_n=10.0, energy_j=2.0 * k).encode(), "", t)
            w.write(keys.NAV_STATE.key(V), StateEstimate.make(
                stamp_ns=t, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x, y_m=0.0,
                psi_rad=0.0).encode(), "", t)
            for a in announced:
                if a.stamp_ns == t:
                    w.write(keys.MISSION_ACCEPTED.key(V), a.encode(), "", t)
            done = math.dist((x, 0.0), wps[-1]) < 1.0
            w.write(keys.MISSION_STATUS.key(V),
                    status(k, mission_id, wps, x, "complete" if done else "active").encode(), "", t)
            k += 1
    w.close(k * DT_NS)
    return path


def probe_file(tmp_path: Path, mission_id: str = "probe") -> Path:
    req = MissionRequest.make(stamp_ns=0, mission_id=mission_id, coa_radius_m=1.0,
                              task_power_w=250.0, waypoints=[Waypoint(x_m=x, y_m=y) for x, y in PROBE])
    path = tmp_path / "probe.json"
    path.write_text(req.model_dump_json())
    return path


def test_a_mission_sent_to_the_live_stack_is_not_reported_as_the_scenarios(tmp_path, capsys) -> None:
    rec = write(tmp_path / "r.mcap", [("probe", PROBE, 200)])
    assert report.main([str(rec), "--no-plots", "--out", str(tmp_path / "rep")]) == 0
    out = capsys.readouterr().out
    assert "mission 'probe': its waypoints are not in the recording" in out
    assert "pass --mission FILE" in out and "state (controller)" in out
    doc = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert doc["metrics"] is None  # no made-up figures from the lake's mission
    (flown,) = doc["missions"]
    assert flown["mission_id"] == "probe" and flown["controller_reported"]["state"] == "complete"
    assert "4 waypoints, the controller flew 2" in flown["fit"]

    # Given the mission that was sent, the report computes its metrics.
    assert report.main([str(rec), "--no-plots", "--json", "--mission",
                        str(probe_file(tmp_path))]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["mission"]["waypoints_m"] == [list(p) for p in PROBE]
    assert doc["metrics"]["completed"] and doc["metrics"]["travel_time_s"] == pytest.approx(19.0, abs=0.15)


def test_each_mission_flown_is_reported_and_a_document_must_fit_it(tmp_path, capsys) -> None:
    # The same waypoints under another id fit (checked against the controller's distances); a
    # different mission with as many waypoints does not.
    other = [(0.0, 0.0), (0.0, 20.0)]  # 20 m east: the controller's distances say otherwise
    rec = write(tmp_path / "r.mcap", [("first", PROBE, 200), ("second", other, 100)])
    assert report.main([str(rec), "--no-plots", "--json", "--mission",
                        str(probe_file(tmp_path, "sent-as-probe"))]) == 0
    doc = json.loads(capsys.readouterr().out)
    first, second = doc["missions"]
    assert first["mission_id"] == "first" and first["metrics"]["completed"]
    assert "its id is 'sent-as-probe', not 'first'" in first["fit"]
    assert second["mission_id"] == "second" and second["metrics"] is None
    assert "off the controller's distances" in second["fit"]
    assert doc["metrics"] is None  # the report is about the last mission flown


def test_a_mission_accepted_as_the_world_restarts_was_not_flown_in_that_episode() -> None:
    """Lockstep: a mission sent after the first completed is taken at the held last period; the
    world then restarts (a new episode) and it is flown there. In the first episode it is one
    status at one instant, not the mission flown."""
    first = [status(k, "first", PROBE, 0.1 * k) for k in range(5)]
    second = [status(5, "second", PROBE, 0.5), status(5, "second", PROBE, 0.5)]
    runs = missions.mission_runs(first + second)
    assert [r.mission_id for r in runs] == ["first"] and runs[0].end_ns == 5 * DT_NS
    assert [r.mission_id for r in missions.mission_runs(second)] == ["second"]  # alone: it counts


# -- the controller's own record of the mission (mission/accepted) comes first -------------------


def test_the_recorded_acceptance_gives_the_metrics_of_a_mission_sent_live(tmp_path, capsys) -> None:
    """The probe mission sent to the live stack, recorded as the controller accepted it (and
    re-published every second, as real time does): full metrics with no document given, even
    with the scenario's mission attached and another document passed."""
    announced = [accepted(k, "probe", PROBE, accepted_k=0) for k in range(0, 200, 10)]
    rec = write(tmp_path / "r.mcap", [("probe", PROBE, 200)], announced)
    assert report.main([str(rec), "--no-plots", "--json", "--scenario", "lake"]) == 0
    doc = json.loads(capsys.readouterr().out)
    (flown,) = doc["missions"]
    assert flown["source"] == f"recorded {keys.MISSION_ACCEPTED.suffix}"
    assert "the controller's own record of it (checked against the controller's distances" \
        in flown["fit"]
    assert doc["mission"] == {"waypoints_m": [list(p) for p in PROBE], "coa_radius_m": 1.0,
                              "task_power_w": 250.0, "source": flown["source"],
                              "controller": "eo-empc", "predict_disturbance": False}
    m = doc["metrics"]
    assert m["completed"] and m["legs_completed"] == 1
    assert m["travel_time_s"] == pytest.approx(19.0, abs=0.15)
    assert m["avg_cross_track_m"] == pytest.approx(0.0, abs=1e-9)  # along the sent path, x axis
    assert m["task_energy_j"] == pytest.approx(250.0 * m["travel_time_s"], rel=1e-9)

    # A document that also fits (same path, other T^w) does not replace the controller's record.
    other = MissionRequest.make(stamp_ns=0, mission_id="probe", coa_radius_m=1.0, task_power_w=1.0,
                                waypoints=[Waypoint(x_m=x, y_m=y) for x, y in PROBE])
    (tmp_path / "other.json").write_text(other.model_dump_json())
    assert report.main([str(rec), "--no-plots", "--json", "--mission",
                        str(tmp_path / "other.json")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["mission"]["task_power_w"] == 250.0
    assert doc["metrics"]["task_energy_j"] == pytest.approx(250.0 * 19.0, abs=250.0 * 0.15)


def test_an_acceptance_counts_only_for_its_own_id_before_the_flight_ended() -> None:
    run = missions.mission_runs([status(k, "probe", PROBE, 0.1 * k) for k in range(50)] +
                                [status(50, "next", PROBE, 0.0)])[0]
    docs = [missions.Candidate(runinfo.Mission(tuple(PROBE), 1.0, 2.0, "a document"), "probe")]
    # Another id's acceptance, or one after the flight ended, is not this flight's: the document.
    for wrong in (accepted(0, "other", PROBE), accepted(51, "probe", PROBE)):
        got = missions.choose(run, missions.acceptances([wrong]), docs, [])
        assert got.mission is not None and got.mission.source == "a document"
        assert got.start_ns == 0
    # Its own: preferred over the document; re-publications are one acceptance.
    mine = [accepted(k, "probe", PROBE, accepted_k=0) for k in (0, 10, 20)]
    assert len(missions.acceptances(mine)) == 1
    got = missions.choose(run, missions.acceptances(mine), docs, [])
    assert got.mission is not None and got.mission.source.startswith("recorded")
    assert (got.mission.waypoints, got.mission.task_power_w, got.start_ns) == (tuple(PROBE), 250.0, 0)
    # Nothing recorded and no document: nothing describes it, and the reason says what was tried.
    none = missions.choose(run, [], [], [])
    assert none.mission is None and "no mission document" in none.how


def test_the_same_id_sent_again_while_it_flew_is_measured_from_its_last_acceptance() -> None:
    """The operator re-sent 'probe' (now 10 m east) 3 s into the flight: the controller restarted it
    under the same id, so the statuses are one stretch; the last acceptance is the path flown."""
    east = [(0.0, 0.0), (0.0, 10.0)]
    statuses = [status(k, "probe", PROBE, 0.1 * k) for k in range(30)] + \
               [status(k, "probe", east, 0.0) for k in range(30, 60)]
    (run,) = missions.mission_runs(statuses)
    got = missions.choose(run, missions.acceptances([accepted(0, "probe", PROBE),
                                                     accepted(30, "probe", east)]), [], [])
    assert got.mission is not None and got.mission.waypoints == tuple(east)
    assert got.start_ns == 30 * DT_NS and "sent again at 3.000 s" in got.how


def test_a_restarted_controllers_resumption_is_the_same_flight() -> None:
    """The controller was killed 3 s in and resumed 'probe' from its checkpoint: it announces the
    mission again (marked ``resumed``), and the flight is still measured from its start."""
    (run,) = missions.mission_runs([status(k, "probe", PROBE, 0.1 * k) for k in range(60)])
    again = accepted(30, "probe", PROBE).model_copy(update={"resumed": True})
    got = missions.choose(run, missions.acceptances([accepted(0, "probe", PROBE), again]), [], [])
    assert got.mission is not None and got.mission.source.startswith("recorded")
    assert got.start_ns == 0 and "sent again" not in got.how


def test_when_the_estimate_completed_the_mission_and_the_true_track_did_not_both_are_said(
        tmp_path, capsys) -> None:
    # The estimate runs 0.6 m ahead of the truth: the controller ends the mission when its estimate
    # enters the 1 m circle at (20, 0), with the true boat still 1.6 m short of the waypoint.
    from seaway_lab.study.execute import not_completed_text

    atts, _ = attachments.scenario_attachments("lake")
    w = RecordingWriter(tmp_path / "r.mcap", attachments=atts, foxglove=False)
    w.open(0)
    for k in range(200):
        x, t = 0.1 * k, k * DT_NS
        w.write(keys.SIM_TRUTH.key(V), SimTruth.make(
            stamp_ns=t, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x, y_m=0.0, psi_rad=0.0,
            thrust_port_n=10.0, thrust_starboard_n=10.0, energy_j=2.0 * k).encode(), "", t)
        w.write(keys.NAV_STATE.key(V), StateEstimate.make(
            stamp_ns=t, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=x + 0.6, y_m=0.0,
            psi_rad=0.0).encode(), "", t)
        done = math.dist((x + 0.6, 0.0), PROBE[-1]) < 1.0
        w.write(keys.MISSION_STATUS.key(V),
                status(k, "probe", PROBE, x + 0.6, "complete" if done else "active").encode(), "", t)
        if done:
            break
    w.close(t)
    args = [str(tmp_path / "r.mcap"), "--no-plots", "--mission", str(probe_file(tmp_path))]
    assert report.main([*args, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert not doc["metrics"]["completed"]
    c = doc["completion"]
    assert (c["track"], c["controller"]) == (False, True)
    assert c["estimate_error_m"] == pytest.approx(0.6, abs=1e-9)
    assert not_completed_text(doc) == (
        "the recording shows the mission not completed on the true track (0 of 1 legs); the "
        "controller completed it on its estimate, 0.60 m from the truth")
    assert report.main([*args, "--out", str(tmp_path / "rep")]) == 0
    lines = capsys.readouterr().out.splitlines()
    row = next(i for i, line in enumerate(lines) if line.startswith("completed"))
    assert lines[row].split()[1] == "NO" and "on the true track" in lines[row]
    assert lines[row + 1].split()[:4] == ["by", "the", "controller", "yes"]
    assert "0.60 m from the truth at the end" in lines[row + 1]
