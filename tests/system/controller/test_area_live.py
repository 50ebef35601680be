"""The operating area through the real processes (issue #57 item 1): a lockstep ``seaway launch
sim-batch`` of the lake (sim, estimator, controller, recorder).

* In flight: the last leg points straight out of the keep-in area at cruise speed (about 1 m/s),
  its end on the boundary: the controller stops the mission short of the edge and holds station,
  saying why (``mission/status``), and no recorded true position of the vessel leaves the area.
  The area the controller enforced is in the recording (``area/active``).
* Before: a mission whose route crosses a keep-out area is refused, the reply naming the leg.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest
from seaway.area.model import OperatingArea
from seaway.contract import keys
from seaway.contract.messages import ActiveArea, MissionRequest, MissionStatus, SimTruth, Waypoint
from seaway.recording import reader
from seaway.runtime.bus import Bus

from tests.conftest import REPO, free_port, stack_credentials, wait_for

pytestmark = pytest.mark.system
EDGE_M = 20.0  # the keep-in area's north edge, through the last waypoint


def _scenario(tmp_path: Path, name: str, mission: str, area: str) -> Path:
    """The lake (its wind, current and sensor noise) with ``mission`` and ``area`` in place of its
    own."""
    text = (REPO / "deploy/scenarios/lake.toml").read_text()
    head = text[:text.index("[mission]")].replace('name = "lake"', f'name = "{name}"', 1)
    path = tmp_path / f"{name}.toml"
    path.write_text(head + mission + area)
    return path


def _env(rendezvous: str) -> dict[str, str]:
    env = dict(os.environ, PYTHONUNBUFFERED="1", SEAWAY_ZENOH_RENDEZVOUS=rendezvous)
    env.pop("SEAWAY_ZENOH_CONFIG", None)
    return env


OUT_AT_THE_END = f"""[mission]
waypoints_m = [[0.0, 0.0], [{EDGE_M}, 0.0]]
coa_radius_m = 0.1
task_power_w = 250.0
controller = "cc-empc"
"""
BOX = f"""
[area.keep_in]
name = "lake"
vertices_m = [[-20.0, -20.0], [{EDGE_M}, -20.0], [{EDGE_M}, 40.0], [-20.0, 40.0]]

[[area.keep_out]]
name = "moored boat"
center_m = [5.0, 10.0]
radius_m = 2.0
"""


@pytest.mark.timeout(600)
@pytest.mark.slow  # a lockstep lake run: tens of seconds, more on a first solver compile
def test_a_last_leg_pointing_out_is_held_at_the_edge_and_never_leaves(procs, tmp_path) -> None:
    scenario = _scenario(tmp_path, "lake-edge", OUT_AT_THE_END, BOX)
    run_dir = tmp_path / "run"
    rendezvous = f"tcp/127.0.0.1:{free_port()}"
    launcher = procs.launch(_env(rendezvous), "sim-batch", "--scenario", str(scenario),
                            "--run-dir", str(run_dir), "--stay")
    with Bus.open("vessel1", identity="operator", credentials=stack_credentials(rendezvous),
                  rendezvous=rendezvous) as bus:
        status = bus.subscribe(keys.MISSION_STATUS, mode="latest")
        held = wait_for(lambda: (s := status.latest()) is not None and s.state in (
            "paused", "complete") and s, 300, what="the mission held (or over)")
        assert held.state == "paused", held
        assert "operating area's edge" in held.reason and "leaves the keep-in area" in held.reason
        assert "scenario lake-edge" in held.reason, held.reason

        # The route check, on the same stack: a way through the moored boat is refused, naming it.
        here = (held.hold_x_m, held.hold_y_m)
        req = MissionRequest.make(stamp_ns=time.time_ns(), mission_id="through", coa_radius_m=2.0,
                                  task_power_w=250.0, controller="cc-empc", join_first_leg=True,
                                  waypoints=[Waypoint(x_m=here[0], y_m=here[1]),
                                             Waypoint(x_m=5.0, y_m=5.0),
                                             Waypoint(x_m=5.0, y_m=15.0)])
        reply = bus.request(keys.MISSION_SET, req, 30.0)
        assert not reply.accepted
        assert "leg 1->2 enters keep-out area keep_out_circles[0] 'moored boat'" in reply.reason
        time.sleep(1.0)
    procs.stop(launcher, signal.SIGINT, 60.0)

    dec = reader.decode_vessel(reader.open_paths([run_dir]), None,
                                  [keys.SIM_TRUTH.suffix, keys.MISSION_STATUS.suffix,
                                   keys.AREA_ACTIVE.suffix])
    truths = [t for t in dec.get(keys.SIM_TRUTH.suffix) if isinstance(t, SimTruth)]
    areas = [a for a in dec.get(keys.AREA_ACTIVE.suffix) if isinstance(a, ActiveArea)]
    assert areas and areas[0].source == "scenario lake-edge"
    area: OperatingArea = areas[0].to_area()
    assert area.keep_in is not None and len(area.keep_out_circles) == 1
    assert len(truths) > 100
    # At cruise speed toward the edge, and never past it.
    assert max(t.u_mps for t in truths) > 0.7
    outside = [(t.x_m, t.y_m) for t in truths if area.why_not_allowed((t.x_m, t.y_m))]
    assert not outside, outside[:5]
    closest = max(t.x_m for t in truths)
    assert closest < EDGE_M
    statuses = [s for s in dec.get(keys.MISSION_STATUS.suffix) if isinstance(s, MissionStatus)]
    assert statuses[-1].state == "paused" and "operating area" in statuses[-1].reason
    print(f"closest approach to the edge: {EDGE_M - closest:.2f} m, held at "
          f"{held.hold_x_m:.2f} m; top speed {max(t.u_mps for t in truths):.2f} m/s")
