"""The lockstep sim applies vehicle I/O's output stage to the controller's demand, through the real
processes: on the lake (the boat's 10 N dead zone) NMPC used to park about 3 m from its first
waypoint for good, its demands of 9.7 to 10.1 N a side swallowed by the dead zone, while vehicle
I/O on a real boat sends such a demand as 10 N (``seaway.vessel.thrusters.output_stage``). Now it
finishes, and every demand inside the dead zone reached the plant as that stage sends it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import SimTruth, ThrustCommand
from seaway.recording import reader
from seaway.vessel.model import load_vessel
from seaway.vessel.thrusters import output_stage

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent


def test_nmpc_finishes_the_lake_with_its_small_demands_sent_as_vehicle_io_sends_them(tmp_path,
                                                                                  zenoh_env) -> None:
    run_dir = tmp_path / "run"
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", "lake",
                          "--controller", "nmpc", "--no-report", "--run-dir", str(run_dir)],
                         env=zenoh_env, capture_output=True, text=True, timeout=300, check=False)
    log = out.stdout[-3000:] + out.stderr[-3000:]
    assert out.returncode == 0 and "mission complete" in out.stdout, log

    dec = reader.decode_vessel([run_dir / "recording.mcap"], None,
                                  [keys.THRUST.suffix, keys.SIM_TRUTH.suffix])
    commands = {m.stamp_ns: m for m in dec.get(keys.THRUST.suffix) if isinstance(m, ThrustCommand)}
    truths = [m for m in dec.get(keys.SIM_TRUTH.suffix) if isinstance(m, SimTruth)]
    boat = load_vessel("paper-boat")
    dz = boat.dead_zone_n
    # The truth at t_k + period holds the thrust applied over (t_k, t_k+1]: the command stamped t_k
    # (no thruster lag on the lake).
    period_ns = truths[1].stamp_ns - truths[0].stamp_ns
    inside = 0
    for truth in truths:
        cmd = commands.get(truth.stamp_ns - period_ns)
        if cmd is None:
            continue
        for demand, applied in ((cmd.thrust_port_n, truth.thrust_port_n),
                                (cmd.thrust_starboard_n, truth.thrust_starboard_n)):
            assert applied == pytest.approx(output_stage(demand, boat), abs=1e-9), (demand, applied)
            inside += 0 < abs(demand) < dz
    assert inside > 0, "no demand fell inside the dead zone: the test proves nothing"
