"""`seaway identify fly`'s pure core: when it flies, what it sends, when it stops."""

from __future__ import annotations

import pytest
from seaway.contract.messages import VehicleStatus
from seaway_lab.identify.live_run import STATUS_STALE_S, TAIL_S, FlyCore
from seaway_lab.identify.manoeuvre import Manoeuvre

WALL_NS = 1_700_000_000_000_000_000


def status(armed: bool = True, link_ok: bool = True, withheld: str | None = None) -> VehicleStatus:
    return VehicleStatus.make(stamp_ns=WALL_NS, autopilot="ardupilot", link_ok=link_ok, armed=armed,
                              mode="MANUAL", thrust_withheld=withheld)


def core(**kw: object) -> FlyCore:
    return FlyCore(Manoeuvre(level_n=3.0), **kw)  # type: ignore[arg-type]


def test_it_sends_neutral_until_the_vessel_takes_thrust_then_flies_from_the_manoeuvres_start() -> None:
    c = core()
    for t in (0.0, 0.1, 0.2):
        cmd = c.step(t, WALL_NS)
        assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0) and c.phase == "waiting"
    c.on_status(0.25, status(armed=False))
    assert c.step(0.3, WALL_NS).thrust_port_n == 0.0 and c.withheld(0.3) == "not armed"
    c.on_status(0.35, status(withheld="disarmed"))
    assert "thrust withheld" in (c.withheld(0.4) or "")
    c.on_status(10.0, status())
    c.step(10.0, WALL_NS)
    assert c.phase == "flying" and c.t_start_s == 10.0
    # 13 s into the manoeuvre: the dead-zone ramp at 0.15 of the level, both thrusters
    c.on_status(23.0, status())
    cmd = c.step(23.0, WALL_NS + 1)
    assert cmd.thrust_port_n == pytest.approx(0.45) and cmd.thrust_starboard_n == pytest.approx(0.45)
    assert cmd.source == "identify" and cmd.stamp_ns == WALL_NS + 1
    assert [c.step(23.0, WALL_NS).seq for _ in range(2)] == [cmd.seq + 1, cmd.seq + 2]


def test_it_aborts_with_the_reason_when_the_autopilot_stops_taking_thrust_mid_run() -> None:
    c = core()
    c.on_status(0.0, status())
    c.step(0.0, WALL_NS)
    c.on_status(30.0, status(withheld="mode"))
    cmd = c.step(30.0, WALL_NS)
    assert c.phase == "aborted" and c.finished
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0)
    assert "30.0 s into the manoeuvre" in c.reason and "mode" in c.reason


def test_a_silent_vehicle_io_aborts_the_flight() -> None:
    c = core()
    c.on_status(0.0, status())
    c.step(0.0, WALL_NS)
    c.step(STATUS_STALE_S - 0.1, WALL_NS)
    assert c.phase == "flying"
    c.step(STATUS_STALE_S + 0.1, WALL_NS)
    assert c.phase == "aborted" and "no vehicle status" in c.reason


def test_it_gives_up_waiting_after_wait_s_saying_what_it_waited_for() -> None:
    c = core(wait_s=5.0)
    c.step(0.0, WALL_NS)
    c.on_status(5.5, status(link_ok=False))
    c.step(5.5, WALL_NS)
    assert c.phase == "aborted" and c.reason == "not flown: after 5 s still no autopilot link"


def test_it_is_done_after_the_manoeuvre_and_a_neutral_tail() -> None:
    c = core()
    c.on_status(0.0, status())
    c.step(0.0, WALL_NS)
    end = c.manoeuvre.duration_s
    c.on_status(end + TAIL_S - 0.5, status())
    cmd = c.step(end + TAIL_S - 0.5, WALL_NS)
    assert c.phase == "flying" and (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0)
    c.step(end + TAIL_S, WALL_NS)
    assert c.phase == "done" and c.finished


def test_a_vessel_file_with_a_dead_zone_is_refused_before_the_bus_opens(
        capsys: pytest.CaptureFixture[str]) -> None:
    # vehicle_io would compensate paper-boat's 10 N dead zone, hiding the boat's own from the ramp.
    from seaway_lab.identify import cli

    assert cli.main(["fly", "--vessel-file", "paper-boat"]) == 2
    err = capsys.readouterr().err
    assert "dead_zone_n = 10 N" in err and "paper-boat" in err and "dead_zone_n is 0" in err
