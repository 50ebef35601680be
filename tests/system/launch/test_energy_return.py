"""The energy budget's return decision through the real processes (issue #17): a lockstep
``seaway launch sim-batch`` of the lake with a battery too small for its mission. The sim drains
its pack and reports it on ``vehicle/battery`` once a second; the controller prices its budget once
a second, and every period once the margin is near 0, and decides the return at the first period
where the energy to get home plus the reserve reaches what is left; it flies home, and the mission
ends there with at least the reserve left. The recording holds every input of the decision, and a
replay of them through a fresh controller core (``seaway_controller.replay``) decides the same
at the same period.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    BatteryState,
    EnergyBudget,
    MissionAccepted,
    MissionStatus,
    StateEstimate,
)
from seaway.recording import reader
from seaway.runtime.bus import Bus
from seaway.vessel.model import load_vessel
from seaway_controller.budget import BUDGET_INTERVAL_NS
from seaway_controller.replay import replay

from tests.conftest import free_port, stack_credentials, wait_for

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent
REPO = Path(__file__).resolve().parents[3]
EXTRA_J = 20_000.0  # above the reserve: the lake mission needs ~30 kJ


def _scenario(tmp_path: Path, extra_j: float = EXTRA_J) -> tuple[Path, float]:
    """The lake, its pack starting with the reserve and ``extra_j`` more (20 kJ), its mission
    forced."""
    vessel = load_vessel("paper-boat")
    assert vessel.battery is not None
    reserve = vessel.battery.reserve_energy_j
    text = (REPO / "deploy/scenarios/lake.toml").read_text()
    text = text.replace('name = "lake"', 'name = "lake-low-battery"', 1)
    text += f"\n[battery]\ninitial_energy_j = {reserve + extra_j}\n"
    # The mission check refuses a mission the battery cannot finish and get home from: the
    # operator forces it, to see the energy budget's return in flight.
    text = text.replace("[mission]\n", "[mission]\nforce = true\n", 1)
    tomllib.loads(text)  # still a valid document
    path = tmp_path / "lake-low-battery.toml"
    path.write_text(text)
    return path, reserve


def _env(rendezvous: str) -> dict[str, str]:
    """This environment on a rendezvous of its own and without a Zenoh config file: the launcher
    makes its stack's credentials, which ``stack_credentials`` then reads."""
    env = dict(os.environ, PYTHONUNBUFFERED="1", SEAWAY_ZENOH_RENDEZVOUS=rendezvous)
    env.pop("SEAWAY_ZENOH_CONFIG", None)
    return env


def _kill_the_controller_at_the_return_decision(procs, run_dir: Path, *launch: str,
                                                interval_s: float) -> subprocess.Popen:
    """``seaway launch LAUNCH``; SIGKILL its controller as soon as the energy budget has decided,
    polled every ``interval_s``; the launcher, once it has exited (within 300 s)."""
    rendezvous = f"tcp/127.0.0.1:{free_port()}"
    launcher = procs.launch(_env(rendezvous), *launch)
    with Bus.open("vessel1", identity="operator", credentials=stack_credentials(rendezvous),
                  rendezvous=rendezvous) as bus:
        energy = bus.subscribe(keys.MISSION_ENERGY, mode="latest")
        wait_for(lambda: (b := energy.latest()) is not None and b.decision != "none", 240,
                 interval_s=interval_s, what="the energy budget's return decision")
        pid = subprocess.run(["pgrep", "-f", f"seaway-controller .*{run_dir}"], capture_output=True,
                             text=True, check=False).stdout.split()
        assert len(pid) == 1, pid
        os.kill(int(pid[0]), signal.SIGKILL)
        try:
            launcher.wait(300)
        except subprocess.TimeoutExpired:
            # Say where the run stood: the launcher's lines and each service's last log lines.
            tails = {p.name: p.read_text(errors="replace")[-2500:]
                     for p in sorted((run_dir / "logs").glob("*.log"))}
            pytest.fail(f"the run did not end within 300 s of the kill\nlauncher:\n"
                        f"{procs.log(launcher)[-3000:]}\n" + "\n".join(
                            f"--- {name}\n{tail}" for name, tail in tails.items()))
    return launcher


def test_a_low_battery_returns_home_and_a_replay_decides_the_same(tmp_path):
    scenario, reserve = _scenario(tmp_path)
    run_dir = tmp_path / "run"
    env = _env(f"tcp/127.0.0.1:{free_port()}")
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", str(scenario),
                          "--run-dir", str(run_dir)], env=env, capture_output=True, text=True,
                         timeout=600, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]

    files = reader.open_paths([run_dir])
    suffixes = [keys.MISSION_ENERGY.suffix, keys.NAV_STATE.suffix, keys.VEHICLE_BATTERY.suffix,
                keys.SOLVE.suffix, keys.MISSION_STATUS.suffix, keys.MISSION_ACCEPTED.suffix,
                keys.SIM_TRUTH.suffix]
    dec = reader.decode_vessel(files, None, suffixes)
    budgets = [b for b in dec.get(keys.MISSION_ENERGY.suffix) if isinstance(b, EnergyBudget)]
    assert budgets, "no mission/energy recorded"
    k = next(i for i, b in enumerate(budgets) if b.decision != "none")
    before, at = budgets[k - 1], budgets[k]
    assert at.decision == "return" and at.decided_ns == at.stamp_ns
    # Priced every period near 0 (``FINE_PRICING_SECONDS``): the decision at the first period
    # where energy to home + reserve reached what is left, not a period early or late.
    states = dec.get(keys.NAV_STATE.suffix)
    assert at.stamp_ns - before.stamp_ns == states[1].stamp_ns - states[0].stamp_ns  # 0.1 s
    assert before.margin_j > 0 >= at.margin_j
    assert before.margin_j - at.margin_j <= 250.0  # one period's fall (~100 J at ~500 W)
    assert at.reserve_j == pytest.approx(reserve)

    # What is left is the sim's last report (once a second, its own integral: initial - used)
    # less what the controller counted since, under a second of the lake's ~500 W.
    batteries = {b.stamp_ns: b for b in dec.get(keys.VEHICLE_BATTERY.suffix)
                 if isinstance(b, BatteryState)}
    report = batteries[max(s for s in batteries if s <= at.stamp_ns)]
    assert at.stamp_ns - report.stamp_ns < BUDGET_INTERVAL_NS
    assert 0.0 <= report.remaining_j - at.battery_remaining_j <= 1000.0

    # Home, with at least the reserve left.
    accepted = [a for a in dec.get(keys.MISSION_ACCEPTED.suffix) if isinstance(a, MissionAccepted)]
    assert [a.mission_id for a in accepted][-1].endswith("/return")
    statuses = [s for s in dec.get(keys.MISSION_STATUS.suffix) if isinstance(s, MissionStatus)]
    assert statuses[-1].state == "complete" and statuses[-1].mission_id.endswith("/return")
    truth = dec.get(keys.SIM_TRUTH.suffix)[-1]
    # Home is where the vessel was (estimated) when the mission was accepted: at the start, to
    # within the estimate's noise; the return ends in home's circle, as the estimate sees it.
    home = (accepted[-1].home_x_m, accepted[-1].home_y_m)
    assert math.dist(home, (0.0, 0.0)) <= 1.0
    assert math.dist((truth.x_m, truth.y_m), home) <= accepted[-1].coa_radius_m + 0.5
    last_battery = batteries[max(batteries)]
    assert last_battery.remaining_j >= reserve

    # The replay: a fresh controller core fed the recorded states and battery reports from the
    # start decides the same, at the same period.
    first = next(a for a in accepted if a.mission_id == at.mission_id)
    states = sorted((s for s in dec.get(keys.NAV_STATE.suffix) if isinstance(s, StateEstimate)),
                    key=lambda s: s.stamp_ns)
    again = replay(first, load_vessel("paper-boat"), states, batteries.values())
    assert again.decision() == (at.decided_ns, "return")
    replayed = {b.stamp_ns: b for b in again.budgets}
    assert replayed[at.stamp_ns].margin_j == pytest.approx(at.margin_j, abs=1e-6)


@pytest.mark.timeout(600)  # a stalled run is reported with its logs after 300 s of waiting
def test_a_controller_killed_at_the_return_decision_flies_home_as_a_return(procs, tmp_path):
    """SIGKILL of the controller as soon as its budget has decided the return: the launcher
    restarts it, and the new one resumes the flight home as the budget's return (its budgets say
    returning, decision 'return'), not as a mission of its own whose 'warn' policy fires at once."""
    scenario, reserve = _scenario(tmp_path, extra_j=8_000.0)  # decided after a few seconds
    run_dir = tmp_path / "run"
    launcher = _kill_the_controller_at_the_return_decision(
        procs, run_dir, "sim-batch", "--scenario", str(scenario), "--run-dir", str(run_dir),
        interval_s=0.002)
    assert launcher.returncode == 0, procs.log(launcher)[-4000:]
    log = (run_dir / "logs" / "controller.log").read_text()
    assert log.count(" starting on vessel") == 2, "the controller was not restarted"
    restarted = log.split(" starting on vessel")[-1]
    assert "resumed mission" in restarted and "Traceback" not in restarted

    dec = reader.decode_vessel(reader.open_paths([run_dir]), None,
                                  [keys.MISSION_ENERGY.suffix, keys.MISSION_STATUS.suffix,
                                   keys.SIM_TRUTH.suffix, keys.VEHICLE_BATTERY.suffix,
                                   keys.MISSION_ACCEPTED.suffix])
    budgets = [b for b in dec.get(keys.MISSION_ENERGY.suffix) if isinstance(b, EnergyBudget)]
    home = [b for b in budgets if b.mission_id.endswith("/return")]
    assert home, "no budget of the return home"
    decided_ns = {b.decided_ns for b in home}
    assert len(decided_ns) == 1  # the one decision, kept through the restart
    assert all(b.returning and b.decision == "return" for b in home), \
        sorted({(b.returning, b.decision) for b in home})
    statuses = [s for s in dec.get(keys.MISSION_STATUS.suffix) if isinstance(s, MissionStatus)]
    assert statuses[-1].state == "complete" and statuses[-1].mission_id.endswith("/return")
    truth = dec.get(keys.SIM_TRUTH.suffix)[-1]
    # Home is explicit: where the vessel was when the mission was accepted (within 1 m of the
    # start); the return ends in its circle as the estimate sees it, within the estimate's noise.
    accepted = [a for a in dec.get(keys.MISSION_ACCEPTED.suffix) if isinstance(a, MissionAccepted)]
    home_m = (accepted[-1].home_x_m, accepted[-1].home_y_m)
    assert math.dist(home_m, (0.0, 0.0)) <= 1.0
    assert math.dist((truth.x_m, truth.y_m), home_m) <= accepted[-1].coa_radius_m + 0.5
    batteries = [b for b in dec.get(keys.VEHICLE_BATTERY.suffix) if isinstance(b, BatteryState)]
    assert batteries[-1].remaining_j >= reserve


@pytest.mark.timeout(600)
@pytest.mark.slow  # a real-time lake mission to its decision, a restart and the way home: ~40 s
def test_real_time_a_controller_killed_at_the_return_decision_flies_home_as_a_return(procs, tmp_path):
    """The same kill in real time (the issue's case: ``seaway launch sim``): the restarted
    controller resumes the way home as the budget's return, without a traceback."""
    scenario, _reserve = _scenario(tmp_path, extra_j=8_000.0)
    run_dir = tmp_path / "run"
    launcher = _kill_the_controller_at_the_return_decision(
        procs, run_dir, "sim", "--scenario", str(scenario), "--run-dir", str(run_dir), "--no-report",
        interval_s=0.01)
    assert launcher.returncode == 0, procs.log(launcher)[-4000:]
    log = (run_dir / "logs" / "controller.log").read_text()
    assert log.count(" starting on vessel") == 2, "the controller was not restarted"
    restarted = log.split(" starting on vessel")[-1]
    assert "resumed mission" in restarted and "Traceback" not in restarted, restarted[-3000:]
    dec = reader.decode_vessel(reader.open_paths([run_dir]), None,
                                  [keys.MISSION_ENERGY.suffix, keys.MISSION_STATUS.suffix])
    home = [b for b in dec.get(keys.MISSION_ENERGY.suffix)
            if isinstance(b, EnergyBudget) and b.mission_id.endswith("/return")]
    assert home and all(b.returning and b.decision == "return" for b in home), \
        sorted({(b.returning, b.decision) for b in home})
    statuses = [s for s in dec.get(keys.MISSION_STATUS.suffix) if isinstance(s, MissionStatus)]
    assert statuses[-1].state == "complete" and statuses[-1].mission_id.endswith("/return")
