"""The launcher's live line (issue 18, item 5): in lockstep it shows simulated time and how many
times faster than real time the run goes; in real time the wall time."""

from __future__ import annotations

import pytest
from seaway.contract.messages import EnergyBudget, MissionStatus, StateEstimate, ThrustCommand
from seaway.tools.launch.status_line import Field, StatusLine, energy_text


def state(t_s: float) -> StateEstimate:
    return StateEstimate(stamp_ns=round(t_s * 1e9), u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.0,
                         y_m=0.0, psi_rad=0.0)


def full(fields: list[Field]) -> list[str]:
    """The fields' whole texts."""
    return [f.full for f in fields]


def test_lockstep_shows_sim_time_and_speed_up() -> None:
    line = StatusLine(["v1"], lockstep=True)
    assert line.time_field(None, 0.2).full == "sim t     - s"
    assert line.time_field(state(1.0), 2.0).full == "sim t     1 s"  # the first state: no rate yet
    assert line.time_field(state(121.0), 4.0).full == "sim t   121 s (  60x real time)"  # 120 s in 2 s
    # The sim holding (the mission complete): the rate stays that of the run, not falling with
    # every wall second that passes.
    assert line.time_field(state(121.0), 30.0).full == "sim t   121 s (  60x real time)"
    assert line.time_field(state(151.0), 31.0).full == "sim t   151 s (   5x real time)"  # 150 s in 29 s
    # A new episode (sim time went back) starts the rate afresh.
    assert line.time_field(state(0.5), 10.0).full == "sim t     0 s"
    assert line.time_field(state(20.5), 11.0).full == "sim t    20 s (  20x real time)"


def test_real_time_shows_wall_time() -> None:
    line = StatusLine(["v1"])
    assert line.time_field(state(500.0), 12.4).full == "t    12 s"
    line.state["v1"] = state(3.0)
    assert line.vessel_text("v1", 7.0).startswith("v1 | t     7 s | no mission status yet")


def test_a_run_without_a_mission_shows_the_latest_thrust_command() -> None:
    line = StatusLine(["v1"], commands=True)
    assert "no mission status yet" in line.vessel_text("v1", 1.0)  # nothing commanded yet
    line.thrust["v1"] = ThrustCommand(stamp_ns=1, thrust_port_n=2.4, thrust_starboard_n=-0.6,
                                      source="identify")
    assert line.vessel_text("v1", 9.0) == "v1 | t     9 s | thrust +2.40 / -0.60 N (identify)"
    line.mission["v1"] = status()  # a mission's status, once there is one, says more
    assert "leg 1/3" in line.vessel_text("v1", 9.0) and "thrust" not in line.vessel_text("v1", 9.0)
    plain = StatusLine(["v1"])  # a run that sends a mission does not show commands before it
    plain.thrust["v1"] = line.thrust["v1"]
    assert "no mission status yet" in plain.vessel_text("v1", 1.0)


# -- the energy budget (issue #17 item 5) ----------------------------------------------------------


def budget(**fields) -> EnergyBudget:
    base = dict(stamp_ns=1, mission_id="box", energy_used_j=1234.0, energy_to_go_j=45_600.0,
                energy_to_home_j=3210.0, home_x_m=0.0, home_y_m=0.0, battery_remaining_j=150_000.0,
                reserve_j=106_000.0, margin_j=40_790.0, policy="return", decision="none")
    return EnergyBudget(**(base | fields))


def status(state: str = "active", mission_id: str = "box") -> MissionStatus:
    return MissionStatus(stamp_ns=1, state=state, mission_id=mission_id, active_leg=1,
                         waypoint_count=4, energy_used_j=7.0, energy_to_go_j=8.0)


def test_energy_text_keeps_three_figures_in_j_kj_mj() -> None:
    assert [energy_text(j) for j in (0.5, 45.61, 330.4, 12_300.0, 106_000.0, 2.5e6, None)] == [
        "0.50 J", "45.6 J", "330 J", "12.3 kJ", "106 kJ", "2.50 MJ", "-"]


def test_the_line_shows_the_budget_of_the_mission_flown() -> None:
    line = StatusLine(["v1"])
    line.mission["v1"] = status()
    # Before any budget: the mission status's own figures.
    assert full(line.energy_fields("v1")) == ["used 7.00 J", "to finish 8.00 J"]
    line.on_energy("v1", budget())
    text = line.vessel_text("v1", 3.0)
    # Energy used is the status's count (every period), not the budget's (priced once a second):
    # the one figure the report gives too (issue 56 item 13).
    assert text.endswith("used 7.00 J | to finish 45.6 kJ | to home 3.21 kJ | "
                         "battery 150 kJ (reserve 106 kJ)"), text
    line.mission["v1"] = status().model_copy(update={"energy_used_j": None})
    assert full(line.energy_fields("v1"))[0] == "used 1.23 kJ"  # a status without one: the budget's
    line.mission["v1"] = status()
    assert "\n" not in text and "RETURN" not in text
    # Another mission's budget (the previous one's last) is not shown against this one.
    line.mission["v1"] = status(mission_id="next")
    assert full(line.energy_fields("v1")) == ["used 7.00 J", "to finish 8.00 J"]


def test_the_decision_says_what_reached_what_at_the_period_it_was_taken() -> None:
    line = StatusLine(["v1"])
    line.mission["v1"] = status()
    reason = "energy to get home 12300 J + reserve 106000 J reached the battery's 118000 J left"
    line.on_energy("v1", budget(energy_to_home_j=12_300.0, battery_remaining_j=118_000.0,
                                margin_j=-300.0, decision="return", decided_ns=50, reason=reason))
    # The return flight's budgets carry the decision on, with figures of their own.
    line.mission["v1"] = status(mission_id="box/return")
    line.on_energy("v1", budget(mission_id="box/return", returning=True, energy_to_home_j=9000.0,
                                battery_remaining_j=117_000.0, decision="return", decided_ns=50,
                                reason=reason))
    text = line.vessel_text("v1", 3.0)
    assert text.endswith("| to home 9.00 kJ | battery 117 kJ (reserve 106 kJ) | RETURNING: energy "
                         "to home 12.3 kJ + reserve 106 kJ reached 118 kJ left"), text
    line.mission["v1"] = status("complete", "box/return")
    assert full(line.energy_fields("v1"))[-1].startswith("RETURNED: energy to home 12.3 kJ")


def test_the_decisions_figures_are_those_of_its_own_period() -> None:
    line = StatusLine(["v1"])
    line.mission["v1"] = status()
    line.on_energy("v1", budget(decision="hold", decided_ns=70))
    line.on_energy("v1", budget(decision="hold", decided_ns=70, energy_to_home_j=1.0))
    assert full(line.energy_fields("v1"))[-1] == ("HOLDING: energy to home 3.21 kJ + reserve 106 kJ "
                                           "reached 150 kJ left")


def test_a_decision_whose_period_was_not_heard_shows_the_controllers_reason() -> None:
    line = StatusLine(["v1"])
    line.mission["v1"] = status()
    line.on_energy("v1", budget(decision="warn", decided_ns=1))
    line.energy["v1"] = budget(decision="warn", decided_ns=2, reason="the controller's words")
    assert full(line.energy_fields("v1"))[-1] == "LOW ENERGY: the controller's words"


def test_on_a_bus_it_shows_the_newest_status_and_state() -> None:
    from seaway.contract import keys
    from seaway.runtime.memory_bus import MemoryBus

    bus = MemoryBus("v1")
    line = StatusLine(["v1"], commands=True)
    line.watch(bus)
    for t in (1.0, 2.0, 3.0):  # in lockstep hundreds a second: only the newest is decoded
        bus.publisher(keys.NAV_STATE).put(state(t))
    received = bus.stats.received
    line.pull()
    assert line.mission["v1"] is None
    assert line.state["v1"] == state(3.0) and bus.stats.received == received + 1
    bus.publisher(keys.THRUST).put(ThrustCommand(stamp_ns=1, thrust_port_n=2.4,
                                                 thrust_starboard_n=-0.6, source="identify"))
    line.show(4.0)
    assert line.thrust["v1"] is not None and line.thrust["v1"].thrust_port_n == 2.4
    bus.publisher(keys.MISSION_STATUS).put(status("complete"))
    assert line.mission["v1"] is None  # read when asked, not when heard
    line.pull()
    assert line.mission["v1"] is not None and line.mission["v1"].state == "complete"
    bus.publisher(keys.MISSION_ENERGY).put(budget(decision="warn", decided_ns=1))
    for _ in range(3):  # later budgets, before the line looks again
        bus.publisher(keys.MISSION_ENERGY).put(budget())
    assert line.decided["v1"] is None  # read when asked ...
    line.pull()
    decided = line.decided["v1"]  # ... and every budget then: a decision's is kept
    assert decided is not None and decided.decision == "warn" and line.energy["v1"] == budget()


# -- fitting the terminal's width (issue #56 item 10) ----------------------------------------------


def busy(vessels: list[str]) -> StatusLine:
    """A line with every field: lockstep time and rate, leg, cross-track, speed, the budget and a
    decision whose period was heard (the longest text there is)."""
    line = StatusLine(vessels, lockstep=True)
    for v in vessels:
        line.mission[v] = MissionStatus(stamp_ns=1, state="active", mission_id="box", active_leg=2,
                                        waypoint_count=5, cross_track_m=-1.25, energy_used_j=7.0)
        line.state[v] = state(10.0)
        line.time_field(line.state[v], 1.0)  # the first state seen, for the rate
        line.state[v] = state(130.0)
        line.on_energy(v, budget(decision="return", decided_ns=5))
    return line


@pytest.mark.parametrize("vessels", [["vessel1"], ["vessel1", "vessel2"]])
@pytest.mark.parametrize("width", [80, 120, 200])
def test_the_line_fits_the_width_keeping_the_most_important_fields(vessels, width) -> None:
    line = busy(vessels)
    whole = line.text(3.0)
    assert len(whole) > 154  # what used to be written whatever the terminal
    fitted = line.text(3.0, width)
    assert len(fitted) <= width, fitted
    assert "\n" not in fitted
    for part in fitted.split(" || "):
        # Always kept: what the mission does, and a decision taken; when, but in a fleet at 80.
        assert "active" in part and "2/4" in part and "RETURN" in part, part
        assert "t 130 s" in part or (len(vessels) > 1 and width == 80), part
    if len(vessels) > 1:
        assert fitted.split(" || ")[1].startswith("vessel2")  # a fleet's lines say whose
    if width >= len(whole):
        assert fitted == whole  # nothing lost when it fits


def test_fit_shortens_then_leaves_out_the_least_important_first() -> None:
    from seaway.tools.launch.status_line import fit

    fields = [Field(0, "alpha"), Field(2, "bravo long", "bravo"), Field(1, "charlie long", "ch")]
    assert fit(fields, None) == "alpha | bravo long | charlie long"
    assert fit(fields, 33) == "alpha | bravo long | charlie long"
    assert fit(fields, 28) == "alpha | bravo | charlie long"  # the least important shortened
    assert fit(fields, 20) == "alpha | bravo | ch"
    assert fit(fields, 12) == "alpha | ch"  # then left out, least important first
    assert fit(fields, 5) == "alpha"
    assert fit(fields, 4) == "a..."  # the most important stays, cut


def test_on_a_terminal_the_line_is_rewritten_in_place_within_its_width() -> None:
    """On a pty of 80 columns: every rewrite starts at the line's start, clears what the previous
    one left beyond its end, and stays within the width, so nothing wraps and no row is left."""
    import fcntl
    import os
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    out = os.fdopen(slave, "w")
    try:
        line = busy(["vessel1", "vessel2"])
        line.out, line.tty = out, out.isatty()
        assert line.tty
        for t in (1.0, 2.0, 3.0):
            line.show(t)
        line.show(4.0, final=True)
        out.flush()
        written = b""
        while not written.endswith(b"\n"):
            written += os.read(master, 65536)
    finally:
        out.close()
        os.close(master)
    text = written.decode().replace("\r\n", "\n")  # the pty's own output translation
    rewrites = text.split("\r")[1:]
    assert len(rewrites) == 4 and text.startswith("\r") and text.count("\n") == 1
    for r in rewrites:
        assert r.rstrip("\n").endswith("\x1b[K")  # clears the rest of the previous line
        assert len(r.rstrip("\n").removesuffix("\x1b[K")) < 80


def test_when_not_a_terminal_whole_lines_are_printed_every_few_seconds(tmp_path) -> None:
    with (tmp_path / "out.txt").open("w") as out:
        line = busy(["vessel1"])
        line.out, line.tty = out, False
        line.show(1.0)
        line.show(1.5)  # within PRINT_EVERY_S: nothing
        line.show(2.0, final=True)
    lines = (tmp_path / "out.txt").read_text().splitlines()
    assert len(lines) == 2 and lines[0] == busy(["vessel1"]).vessel_text("vessel1", 1.0)


def test_a_motion_fault_is_shown_beside_the_mission_and_kept_when_the_line_is_short() -> None:
    line = StatusLine(["v1"])
    line.mission["v1"] = MissionStatus(stamp_ns=1, state="paused", active_leg=1, waypoint_count=4,
                                       cross_track_m=0.05)
    line.state["v1"] = state(3.0)
    assert "FAULT" not in line.vessel_text("v1", 7.0)
    line.state["v1"] = state(3.0).model_copy(update={"motion_fault": "not_moving"})
    text = line.vessel_text("v1", 7.0)
    assert "paused leg 1/3 | xte  0.05 m | MOTION FAULT not_moving | speed" in text, text
    assert "FAULT not_moving" in line.vessel_text("v1", 7.0, width=40)  # before the speed and xte


def test_a_thruster_short_of_its_command_is_shown_and_kept_when_the_line_is_short() -> None:
    line = StatusLine(["v1"])
    line.mission["v1"] = MissionStatus(stamp_ns=1, state="active", active_leg=2, waypoint_count=4,
                                       cross_track_m=0.05)
    line.state["v1"] = state(3.0)
    assert "THRUSTER" not in line.vessel_text("v1", 7.0)
    line.state["v1"] = state(3.0).model_copy(update={"thrust_short_side": "port",
                                                     "thrust_short_frac": 0.52})
    text = line.vessel_text("v1", 7.0)
    assert "xte  0.05 m | PORT THRUSTER 52 % SHORT | speed" in text, text
    assert "PORT -52%" in line.vessel_text("v1", 7.0, width=40)  # before the speed and xte
    # A motion fault says more: it stands alone.
    line.state["v1"] = line.state["v1"].model_copy(update={"motion_fault": "not_moving"})
    text = line.vessel_text("v1", 7.0)
    assert "MOTION FAULT" in text and "THRUSTER" not in text


@pytest.mark.parametrize("lockstep", [True, False])
def test_valid_but_absurd_values_show_a_question_mark_and_never_raise(lockstep) -> None:
    """The launcher redraws the line with no handler around it: a schema-valid but absurd value
    (a finite 1e200 m/s, a stamp at the int64 end, 1e300 J) shows '?' where it would go."""
    line = StatusLine(["v1"], lockstep=lockstep, commands=True)
    line.state["v1"] = StateEstimate(stamp_ns=2**63 - 1, u_mps=1e200, v_mps=1e200, r_radps=0.0,
                                     x_m=0.0, y_m=0.0, psi_rad=0.0)
    line.thrust["v1"] = ThrustCommand(stamp_ns=1, thrust_port_n=1e300, thrust_starboard_n=-0.6,
                                      source="identify")
    text = line.vessel_text("v1", 3.0)
    assert "speed    ? m/s" in text and "thrust ? / -0.60 N" in text
    assert ("sim t ? s" in text) == lockstep
    line.mission["v1"] = MissionStatus(stamp_ns=1, state="active", mission_id="box", active_leg=1,
                                       waypoint_count=4, cross_track_m=1e300, energy_used_j=1e300)
    line.energy["v1"] = budget(energy_to_go_j=1e300, battery_remaining_j=1e300)
    text = line.vessel_text("v1", 4.0)
    assert "xte ? m" in text and "used ? MJ" in text and "to finish ? MJ" in text
    assert len(text) < 200


def test_a_field_that_cannot_be_made_shows_a_question_mark_the_rest_stays(caplog) -> None:
    line = StatusLine(["v1"], commands=True)
    line.state["v1"] = state(3.0)
    line.mission["v1"] = status()
    line.energy["v1"] = budget()

    def broken(vessel: str) -> list[Field]:
        raise OverflowError("int too large to convert to float")

    line.energy_fields = broken  # type: ignore[method-assign]
    line.mission_fields = broken  # type: ignore[method-assign]
    assert full(line.fields("v1", 1.0)) == ["v1", "t     1 s", "mission ?", "speed 1.00 m/s",
                                            "energy ?"]
    assert "cannot show its energy" in caplog.text


def test_a_run_going_on_without_its_recorder_says_so_before_the_figures() -> None:
    """The recorder failed for good and a real-time run flies on: the line says it is not
    recording, ranked with the decisions, so a narrow terminal keeps it over the figures."""
    line = StatusLine(["v1"])
    line.state["v1"] = state(3.0)
    line.mission["v1"] = status()
    assert not any("RECORD" in f for f in full(line.fields("v1", 5.0)))
    line.without = {"v1": ["recorder", "groundstation"]}
    texts = full(line.fields("v1", 5.0))
    assert "NOT RECORDING" in texts and "NO GROUNDSTATION" in texts
    assert texts.index("NOT RECORDING") < texts.index(next(t for t in texts if t.startswith("speed")))
    narrow = line.vessel_text("v1", 5.0, width=40)
    assert "NOT REC" in narrow and "speed" not in narrow
