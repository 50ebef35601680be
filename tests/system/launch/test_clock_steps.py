"""A wall clock stepped under a flying real-time stack, as NTP or GPS time steps a Raspberry Pi's
clock (no real-time clock: it boots at the last saved time) while every process runs.

libfaketime gives every process of ``seaway launch sim`` one wall clock, stepped by rewriting its
timestamp file; the monotonic clock is left alone (FAKETIME_DONT_FAKE_MONOTONIC). Mid-mission, the
wall clock steps an hour forward or back. Checked: the energy count takes no step for thrust (no
phantom energy, no return home: ``seaway_controller.core_energy``), the estimator drops its state
and starts again on the stepped clock either way (``seaway_estimator.core_estimate``), and thrust
reaches the vessel again within seconds, with no process found hung or restarted.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.recording import reader
from seaway.runtime.bus import Bus
from seaway.runtime.credentials import ENV_CREDENTIALS

from tests.conftest import REPO, wait_for
from tests.system.launch.test_hangs_and_stops import of
from tests.unit.recorder.foxglove_check import invalid_messages

pytestmark = pytest.mark.system
# The thread-safe build: the other one, read from many threads at once (Zenoh's), now and then
# returns the clock unstepped (245 of 230 000 reads in a test of 6 threads).
LIBFAKETIME = Path("/usr/lib/x86_64-linux-gnu/faketime/libfaketimeMT.so.1")
HOUR_S = 3600
AFTER_STEP_S = 12.0  # watched after the step: the budget prices once a second
# A generous bound on what 12 s of the lake mission draws (about 0.5 kJ/s); the step's phantom
# energy was 900 kJ.
MAX_DRAW_J = 30_000.0
# Thrust back at the vessel within this after the step: the estimator starts again from the next
# fix and heading (about 1.3 s either way). That it is within the launcher's liveness bound (5 s) is
# checked by no process being found hung; this bound only leaves room for a loaded machine.
THRUST_BACK_S = 10.0
RC_LOSS_S = 5.0
"""The simulated PX4's COM_RC_LOSS_T in these runs [s] (its default is 0.5 s). libfaketime re-reads
its timestamp file at every clock read, and on a loaded two-core machine vehicle_io was then
starved of the CPU for half a second now and then: the simulated autopilot's radio-loss failsafe
took the vessel and paused the mission, which is not what these tests are about."""

# libfaketime 0.9.10 (Debian 12, Ubuntu 24.04) breaks clock_nanosleep(CLOCK_MONOTONIC,
# TIMER_ABSTIME) under FAKETIME_DONT_FAKE_MONOTONIC (wolfcw/libfaketime#426): Python >= 3.11's
# time.sleep raises EINVAL. Each process waits on a monotonic Event instead (the same clock).
SLEEP_SHIM = '''import threading, time
def _sleep(seconds):
    if seconds < 0:
        raise ValueError("sleep length must be non-negative")
    threading.Event().wait(seconds)
time.sleep = _sleep
'''


class Watch:
    """What the test hears, with its own receive times (monotonic)."""

    def __init__(self, bus: Bus) -> None:
        self.lock = threading.Lock()
        self.budgets: list[tuple[float, object]] = []
        self.thrust_at_vessel: list[float] = []  # receive times of sim/truth with thrust on
        self.status = None
        bus.subscribe(keys.MISSION_ENERGY,
                      callback=lambda _k, m: self._add(self.budgets, (time.monotonic(), m)))
        bus.subscribe(keys.MISSION_STATUS, callback=lambda _k, m: setattr(self, "status", m))
        bus.subscribe(keys.SIM_TRUTH, callback=self._on_truth)

    def _on_truth(self, _key: str, m) -> None:
        if m.thrust_port_n != 0.0 or m.thrust_starboard_n != 0.0:
            self._add(self.thrust_at_vessel, time.monotonic())

    def _add(self, seq: list, item: object) -> None:
        with self.lock:
            seq.append(item)


def tolerant_profile(tmp: Path) -> Path:
    """The ``sim`` profile with the simulated autopilot's radio loss after ``RC_LOSS_S``."""
    text = (REPO / "deploy" / "profiles" / "sim.toml").read_text()
    anchor = '"--param", "NAV_RCL_ACT=1",'
    assert text.count(anchor) == 1, "the sim profile's PX4 parameters moved"
    profile = tmp / "sim-tolerant.toml"
    profile.write_text(text.replace(anchor, f'{anchor} "--param", "COM_RC_LOSS_T={RC_LOSS_S:g}",'))
    return profile


def faketime_env(env: dict[str, str], tmp: Path) -> tuple[dict[str, str], Path]:
    shim = tmp / "faketime-shim"
    shim.mkdir()
    (shim / "sitecustomize.py").write_text(SLEEP_SHIM)
    stamp = tmp / "faketime"
    stamp.write_text("+0\n")
    return dict(env, LD_PRELOAD=str(LIBFAKETIME), FAKETIME_TIMESTAMP_FILE=str(stamp),
                FAKETIME_NO_CACHE="1", FAKETIME_DONT_FAKE_MONOTONIC="1",
                PYTHONPATH=os.pathsep.join(p for p in (str(shim), env.get("PYTHONPATH")) if p)), stamp


def step_clock(stamp: Path, offset_s: int) -> None:
    """Every process's wall clock, ``offset_s`` off the real one, at once (an atomic rename: a
    process never reads a half-written file)."""
    new = stamp.with_suffix(".new")
    new.write_text(f"{offset_s:+d}\n")
    os.replace(new, stamp)


@pytest.mark.skipif(not LIBFAKETIME.exists(), reason="libfaketime is not installed (apt-get install "
                    "faketime): it steps the stack's wall clock")
@pytest.mark.parametrize("step_s", [HOUR_S, -HOUR_S], ids=["hour-forward", "hour-back"])
def test_a_wall_clock_step_mid_mission_neither_drains_the_battery_nor_stops_control(
        procs, zenoh_env, tmp_path, step_s) -> None:
    env, stamp = faketime_env(zenoh_env, tmp_path)
    run = tmp_path / "run"
    la = procs.launch(env, str(tolerant_profile(tmp_path)), "--run-dir", str(run), "--stay",
                      "--no-report")
    with Bus.open("vessel1") as bus:
        w = Watch(bus)
        wait_for(lambda: w.budgets and w.budgets[-1][1].battery_remaining_j is not None
                 and w.status is not None and w.status.state == "active", 120,
                 what="the mission flying with a battery figure")
        before = w.budgets[-1][1]
        t_step = time.monotonic()
        step_clock(stamp, step_s)
        back = wait_for(lambda: next((t for t in list(w.thrust_at_vessel) if t > t_step + 0.5), None),
                        THRUST_BACK_S, what="thrust at the vessel after the step")
        print(f"step {step_s:+d} s: thrust on at the vessel again {back - t_step:.1f} s after it")
        time.sleep(max(0.0, AFTER_STEP_S - (time.monotonic() - t_step)))
        after = [m for t, m in list(w.budgets) if t > t_step]
    assert la.poll() is None, procs.log(la)[-3000:]
    assert after, "no mission/energy after the step"
    assert not any(m.returning for m in after), [m.returning for m in after]
    used = max(m.energy_used_j for m in after) - before.energy_used_j
    drawn = before.battery_remaining_j - min(m.battery_remaining_j for m in after
                                             if m.battery_remaining_j is not None)
    print(f"step {step_s:+d} s: energy used {used:.0f} J, battery drawn {drawn:.0f} J in "
          f"{AFTER_STEP_S:.0f} s")
    assert used < MAX_DRAW_J and drawn < MAX_DRAW_J, (used, drawn)
    procs.stop(la, timeout_s=60)
    events = [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines()]
    assert not [e for e in events if e["event"] in ("hung", "exit")], events  # none restarted
    # The recorder says the step, once, on its own logger, with its size (the clock's offset from
    # the monotonic one at two flushes 50 ms apart: within a second of the step).
    said = [float(m.group(1)) for m in re.finditer(
        r" WARNING seaway\.recorder\.clock: \D*([-+]\d+\.\d+) s", (run / "logs" / "recorder.log")
        .read_text())]
    assert len(said) == 1 and abs(said[0] - step_s) < 1.0, said
    # And it records the step (one record, its size), which the report bridges when forward: the
    # mission's samples then span the minutes it flew, not the hour the clock jumped. A step back is
    # not bridged, and the report of such a run may read either side of it as the run, or refuse
    # ("no state sample after the mission started"): not asserted.
    steps = [json.loads(m.data) for m in reader.iter_messages(reader.open_paths([run]))
             if m.topic == "recorder/clock_step"]
    assert len(steps) == 1 and abs(steps[0]["step_ns"] / 1e9 - step_s) < 1.0, steps
    if step_s > 0:
        out = subprocess.run([str(Path(sys.executable).parent / "seaway"), "report", str(run),
                              "--no-plots", "--json", "--out", str(tmp_path / "report")],
                             env=zenoh_env, capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr[-3000:]
        doc = json.loads(out.stdout)
        (step,) = doc["recording"]["clock_steps"]
        assert abs(step["step_s"] - step_s) < 1.0 and step["bridged"], step
        met = doc["metrics"]
        assert (met["end_ns"] - met["start_ns"]) / 1e9 < 600, met
    # The step's record validates against the schema its channel carries (jsonschema alone), as
    # does everything else in the file.
    checked, invalid = invalid_messages(run / "recording.mcap")
    assert checked > 1000 and invalid == {}, {t: e[0] for t, e in invalid.items()}


@pytest.mark.skipif(not LIBFAKETIME.exists(), reason="libfaketime is not installed (apt-get install "
                    "faketime): it sets the stack's wall clock back")
def test_a_stack_whose_clock_runs_days_behind_its_credentials_starts(procs, zenoh_env,
                                                                      tmp_path) -> None:
    """Credentials made on the shore with the right time, a boat's stack whose clock runs two days
    behind (no real-time clock, no network yet): it starts, every process ready, and flies. A
    certificate valid only from the moment it was made would be "not yet valid" to every process's
    TLS, and no process could join (``seaway.runtime.credentials.VALID_FROM``)."""
    creds = tmp_path / "credentials"
    made = subprocess.run([sys.executable, "-m", "seaway.tools.cli", "credentials", "create",
                           str(creds)], env=zenoh_env, capture_output=True, text=True, timeout=60,
                          check=False)
    assert made.returncode == 0, made.stderr
    env, stamp = faketime_env(zenoh_env, tmp_path)
    step_clock(stamp, -2 * 86_400)  # before any process starts
    env[ENV_CREDENTIALS] = str(creds)
    run = tmp_path / "run"
    la = procs.launch_ready(env, str(tolerant_profile(tmp_path)), "--run-dir", str(run), "--stay",
                            "--no-report", timeout_s=120)

    def flying() -> bool:  # from the recording as it is written (the reader repairs a cut copy)
        dec = reader.decode_vessel(reader.open_paths([run]), "vessel1",
                                   [keys.MISSION_STATUS.suffix, keys.SIM_TRUTH.suffix])
        status, truth = dec.get(keys.MISSION_STATUS.suffix), dec.get(keys.SIM_TRUTH.suffix)
        thrusting = [m for m in truth if m.thrust_port_n or m.thrust_starboard_n]
        # Stamped on the stack's clock: two days behind the credentials.
        assert not truth or time.time_ns() - truth[-1].stamp_ns > 86_400 * 10**9
        return bool(status) and status[-1].state == "active" and len(thrusting) > 20

    wait_for(flying, 90, interval_s=2.0, what="the mission flying, thrust at the vessel")
    procs.stop(la, timeout_s=60)


@pytest.mark.skipif(not LIBFAKETIME.exists(), reason="libfaketime is not installed (apt-get install "
                    "faketime): it boots the stack at 1970")
def test_a_stack_booted_at_1970_restarts_a_process_after_gps_time_arrives(procs, zenoh_env,
                                                                          tmp_path) -> None:
    """A boat with no real-time clock and no saved time boots at 1970, and the launcher makes the
    run's own authority then. GPS time arrives, 56 years later, and only then a process dies: the
    launcher's restart must still join the stack. With the run's certificates valid for 30 days
    from the moment they were made, they had expired by then (in 1970), and the restarted process
    could never open its session (``seaway.tools.launch.authority``)."""
    env, stamp = faketime_env(zenoh_env, tmp_path)
    env.pop(ENV_CREDENTIALS)  # the launcher makes the run's own authority, at the stack's time
    step_clock(stamp, 86_400 - int(time.time()))  # 1970-01-02, before any process starts
    run = tmp_path / "run"
    la = procs.launch_ready(env, str(tolerant_profile(tmp_path)), "--run-dir", str(run), "--stay",
                            "--no-report", timeout_s=120)

    def truth() -> list:
        """The sim's truth in the recording as it is written (the reader repairs a cut copy). The
        simulated vessel's time runs on from its start, on the monotonic clock: it takes no step."""
        dec = reader.decode_vessel(reader.open_paths([run]), "vessel1", [keys.SIM_TRUTH.suffix])
        return dec.get(keys.SIM_TRUTH.suffix)

    def thrust_since(stamp_ns: int) -> int:
        return sum(1 for m in truth()
                   if m.stamp_ns >= stamp_ns and (m.thrust_port_n or m.thrust_starboard_n))

    wait_for(lambda: thrust_since(0) > 20, 90, interval_s=2.0, what="thrust at the vessel in 1970")
    step_clock(stamp, 0)  # GPS time: the real one
    time.sleep(2.0)
    (ctl,) = of(run, "controller", "start")
    os.kill(ctl["pid"], signal.SIGKILL)
    killed_ns = truth()[-1].stamp_ns
    wait_for(lambda: len(of(run, "controller", "start")) == 2, 30, what="the controller restarted")
    # The restarted controller resumes the mission: thrust at the vessel again. The watchdog zeroes
    # the dead one's thrust within 0.3 s, so thrust 3 s of simulated time on is the new one's.
    wait_for(lambda: thrust_since(killed_ns + 3 * 10**9) > 20, 60, interval_s=2.0,
             what="thrust from the restarted controller")
    assert la.poll() is None, procs.log(la)[-3000:]
    procs.stop(la, timeout_s=60)
