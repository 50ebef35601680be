"""The launcher's live line (issue 18, item 5): in lockstep it shows simulated time and how many
times faster than real time the run goes; in real time the wall time."""

from __future__ import annotations

from seaway.contract.messages import StateEstimate
from seaway.tools.launch.main import StatusLine


def state(t_s: float) -> StateEstimate:
    return StateEstimate(stamp_ns=round(t_s * 1e9), u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.0,
                         y_m=0.0, psi_rad=0.0)


def test_lockstep_shows_sim_time_and_speed_up() -> None:
    line = StatusLine(["v1"], lockstep=True)
    assert line.time_text(None, 0.2) == "sim t     - s"
    assert line.time_text(state(1.0), 2.0) == "sim t     1 s"  # the first state: no rate yet
    assert line.time_text(state(121.0), 4.0) == "sim t   121 s (  60x real time)"  # 120 s in 2 s
    # A new episode (sim time went back) starts the rate afresh.
    assert line.time_text(state(0.5), 10.0) == "sim t     0 s"
    assert line.time_text(state(20.5), 11.0) == "sim t    20 s (  20x real time)"


def test_real_time_shows_wall_time() -> None:
    line = StatusLine(["v1"])
    assert line.time_text(state(500.0), 12.4) == "t    12 s"
    line.state["v1"] = state(3.0)
    assert line.vessel_text("v1", 7.0).startswith("v1 | t     7 s | no mission status yet")
