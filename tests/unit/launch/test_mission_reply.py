"""What the launcher prints of the controller's reply to the mission it sent (issue 56 item 13)."""

from __future__ import annotations

from seaway.contract.messages import MissionRequest, Reply, Waypoint
from seaway.tools.launch.startup_requests import mission_reply_lines


def request(controller: str) -> MissionRequest:
    return MissionRequest.make(
        stamp_ns=1,
        mission_id="lake",
        controller=controller,
        waypoints=[Waypoint(x_m=0.0, y_m=0.0), Waypoint(x_m=10.0, y_m=0.0)],
        coa_radius_m=1.0,
        task_power_w=250.0,
    )


def test_a_controller_whose_energy_prediction_is_known_poor_gets_a_warning() -> None:
    lines = mission_reply_lines(request("nmpc"), Reply.accept(1, "mission started"))
    assert lines[0].startswith("mission lake: accepted (nmpc")
    assert len(lines) == 2 and lines[1].startswith("WARNING") and "nmpc" in lines[1]
    assert mission_reply_lines(request("cc-empc"), Reply.accept(1, "mission started")) == [
        "mission lake: accepted (cc-empc, tau_d = 0, T^w 250 W)"
    ]
    refused = mission_reply_lines(request("nmpc"), Reply.refuse(1, "no"))
    assert len(refused) == 1 and "REFUSED: no" in refused[0]  # nothing to warn about
