"""The run description through the real processes (lockstep): one place for the control period and the
vessel files, a plant that differs from the model, and a mismatch between two services refused.

Each run is a real ``seaway launch sim-batch``: sim, estimator, controller and recorder as separate
processes on their own Zenoh rendezvous, a real MCAP file and the real report.
"""

from __future__ import annotations

import itertools
import json
import statistics
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import ClockTick, SolveRecord, StateEstimate, ThrustCommand
from seaway.recording import reader, runinfo
from seaway.vessel.model import load_vessel

from tests.conftest import wait_for

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent


def _launch(tmp: Path, env: dict[str, str], *args: str, timeout_s: float = 400.0) -> Path:
    run_dir = tmp / "run"
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--run-dir", str(run_dir), *args],
                         env=env, capture_output=True, text=True, timeout=timeout_s, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return run_dir


def _report(run_dir: Path) -> dict:
    return json.loads((run_dir / "report" / "metrics.json").read_text())


def _stamps(msgs: list) -> list[int]:
    return sorted({m.stamp_ns for m in msgs})


def _median_step_s(stamps: list[int]) -> float:
    return statistics.median(b - a for a, b in itertools.pairwise(stamps)) / 1e9


def test_the_control_period_is_set_in_one_place_and_every_service_and_the_report_follow(
        tmp_path, zenoh_env) -> None:
    # NMPC: condition #1 in about 36 s of simulated time (180 periods of 0.2 s), not CC-EMPC's 333 s.
    run_dir = _launch(tmp_path, zenoh_env, "--scenario", "paper-c1", "--controller", "nmpc",
                      "--control-period-s", "0.2")
    run = json.loads((run_dir / "run.json").read_text())
    assert run["control_period_s"] == 0.2 and run["clock"] == "lockstep"
    files = [run_dir / "recording.mcap"]
    atts = reader.read_info(files).attachments
    assert runinfo.run_from_attachments(atts).control_period_s == 0.2  # the recording carries the run
    dec = reader.decode_vessel(files, None, [keys.SIM_CLOCK.suffix, keys.NAV_STATE.suffix,
                                                keys.THRUST.suffix, keys.SOLVE.suffix])
    ticks = [m for m in dec.get(keys.SIM_CLOCK.suffix) if isinstance(m, ClockTick)]
    states = [m for m in dec.get(keys.NAV_STATE.suffix) if isinstance(m, StateEstimate)]
    thrusts = [m for m in dec.get(keys.THRUST.suffix) if isinstance(m, ThrustCommand)]
    # The simulator steps, the estimator publishes and the controller commands every 0.2 s of sim time.
    for name, msgs in (("sim/clock", ticks), ("nav/state", states), ("ctrl/thrust", thrusts)):
        assert _median_step_s(_stamps(msgs)) == pytest.approx(0.2, abs=1e-9), name
    # The controller's OCP predicts in steps of 0.2 s: consecutive predicted positions are about
    # speed x 0.2 s apart (at 0.1 s they would be half that).
    solves = [m for m in dec.get(keys.SOLVE.suffix) if isinstance(m, SolveRecord) and m.success]
    ratios = []
    by_stamp = {s.stamp_ns: s for s in states}
    for rec in solves[20::5]:  # under way, each leg
        st = by_stamp.get(rec.stamp_ns)
        speed = (st.u_mps ** 2 + st.v_mps ** 2) ** 0.5 if st is not None else 0.0
        if speed > 0.02 and len(rec.predicted_x_m) > 2:  # not turning on the spot
            dx = rec.predicted_x_m[2] - rec.predicted_x_m[1]
            dy = rec.predicted_y_m[2] - rec.predicted_y_m[1]
            ratios.append((dx * dx + dy * dy) ** 0.5 / speed)
    assert len(ratios) >= 10 and statistics.median(ratios) == pytest.approx(0.2, rel=0.15), ratios
    assert "control period (OCP dt) 0.2 s" in (run_dir / "logs" / "controller.log").read_text()
    report = _report(run_dir)
    met = report["metrics"]
    assert report["control_period_s"] == 0.2 and met["completed"] and met["legs_completed"] == 2
    # One cross-track sample per period outside the circles: at most travel_time / 0.2 of them.
    assert 0.7 * met["travel_time_s"] / 0.2 < met["cross_track_samples"] <= met["travel_time_s"] / 0.2 + 1
    assert report["solve"]["count"] == pytest.approx(met["travel_time_s"] / 0.2, abs=3)


@pytest.mark.slow  # a whole CC-EMPC paper mission, about 29 s
def test_a_plant_that_differs_from_the_model_flies_condition_4(tmp_path, zenoh_env) -> None:
    model, plant = load_vessel("paper-sim"), load_vessel("paper-sim-perturbed")
    # The shipped perturbed plant is what the issue asks: m11, m22 +20 %, Xu, Yv -20 %, rest equal.
    for field, factor in (("m11_kg", 1.2), ("m22_kg", 1.2), ("xu_kgps", 0.8), ("yv_kgps", 0.8)):
        assert getattr(plant, field) == pytest.approx(factor * getattr(model, field)), field
    same = {"m33_kgm2", "nr_kgm2ps", "arm_m", "alpha_w_per_n2", "thrust_max_n", "reverse_max_n"}
    assert all(getattr(plant, f) == getattr(model, f) for f in same)

    run_dir = _launch(tmp_path, zenoh_env, "--scenario", "paper-c4-perturbed")
    run = json.loads((run_dir / "run.json").read_text())
    assert (run["model_vessel_file"], run["plant_vessel_file"]) == ("paper-sim", "paper-sim-perturbed")
    sim_log = (run_dir / "logs" / "sim.log").read_text()
    assert "plant vessel paper-sim-perturbed, model vessel paper-sim" in sim_log
    assert "model paper-sim" in (run_dir / "logs" / "controller.log").read_text()
    atts = reader.read_info([run_dir / "recording.mcap"]).attachments
    assert any(n.startswith("plant-vessel/") for n in atts) and any(n.startswith("vessel/") for n in atts)
    met = _report(run_dir)["metrics"]
    assert met["completed"] and met["legs_completed"] == 2
    # The lighter-damped plant is faster than the model believes: it arrives well before the
    # nominal 329.3 s of condition #4, so the plant really was the perturbed one.
    assert met["travel_time_s"] < 300.0
    assert met["avg_cross_track_m"] < 1.0


def test_two_services_told_different_runs_refuse_at_start(procs, zenoh_env) -> None:
    est = procs.start([str(BIN / "seaway-estimator"), "--scenario", "paper-c1", "--lockstep"],
                      zenoh_env, "estimator")
    wait_for(lambda: "ready on vessel" in procs.log(est), 20, what="estimator ready")
    sim = procs.start([str(BIN / "seaway-sim"), "--scenario", "paper-c1", "--lockstep",
                       "--control-period-s", "0.2"], zenoh_env, "sim")
    assert sim.wait(timeout=20) == 2
    log = procs.log(sim)
    assert "control_period_s: 0.2 here, 0.1 there" in log and "estimator" in log, log[-2000:]
    assert est.poll() is None  # the running service is untouched
    # Told the same run, the simulator starts.
    ok = procs.start([str(BIN / "seaway-sim"), "--scenario", "paper-c1", "--lockstep"], zenoh_env, "sim2")
    wait_for(lambda: "ready on vessel" in procs.log(ok), 20, what="sim ready")


def test_flags_beside_a_run_file_are_refused(procs, zenoh_env, tmp_path) -> None:
    run = tmp_path / "run.json"
    run.write_text(json.dumps({"run_id": "r", "vessel": "vessel1", "scenario": "paper-c1"}))
    p = procs.start([str(BIN / "seaway-sim"), "--run", str(run), "--control-period-s", "0.2"],
                    zenoh_env, "sim")
    assert p.wait(timeout=20) == 2
    assert "--control-period-s given beside --run" in procs.log(p)
