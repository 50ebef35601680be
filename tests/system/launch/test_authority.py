"""Authority on a live stack: intruders move nothing and stop nothing; the operator still can.

The real ``sim`` profile (simulated PX4 over MAVLink, vehicle_io, estimator, controller, recorder)
runs a short lake mission (one 25 m leg, about 25 s, of which start-up, the attack and the checks
take about 10) with the credentials the launcher makes for the run. Three intruders attack it while
it runs, each with every attack of issue #15 (forged thrust at 50 Hz, disarm and
force-disarm, mode HOLD, a mission 4.9 km away, abort, navigation reset, a forged "complete"):

* ``no credential``: a plain session on the stack's rendezvous port;
* ``another authority``: a certificate from another stack's authority (the harness identity, which
  may do everything in its own stack);
* ``insider``: the stack's own estimator certificate (a compromised process of the stack that is
  not an operator and does not produce ``ctrl/thrust``).

Nothing they send arrives: no forged thrust is seen by any process of the stack (nor recorded),
the vehicle stays armed in MANUAL, the mission stays the launcher's, the launcher does not stop
early, and every request goes unanswered. The operator identity's requests (pause, resume) are
answered. The run's MAVLink is signed, and the signed run completes the mission. A lockstep run
with a forging insider ends with the undisturbed run's energy.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    ArmRequest,
    MissionCommand,
    MissionRequest,
    MissionStatus,
    ModeRequest,
    NavResetRequest,
    Refusals,
    ThrustCommand,
    Waypoint,
)
from seaway.recording.reader import iter_messages, open_paths
from seaway.runtime import credentials, stacks
from seaway.runtime.bus import Bus

from tests.conftest import stack_credentials, wait_for
from tests.system.hardening.stack import short_lake

pytestmark = pytest.mark.system
VESSEL = "vessel1"
FORGED_N = (61.5, -61.5)  # a spin on the spot: valid, and unmistakable if it ever arrived


def _stack_env(zenoh_env: dict[str, str], monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """The launcher makes its own credentials; this test finds them through the stack registry."""
    env = dict(zenoh_env)
    for name in (credentials.ENV_CREDENTIALS, credentials.ENV_IDENTITY):
        env.pop(name, None)
        monkeypatch.delenv(name, raising=False)
    return env


def _attack(bus: Bus, mission_id: str, duration_s: float) -> list[str]:
    """Every attack from one intruder session; returns what any request got back, accepted or not."""
    thrust = bus.publisher(keys.THRUST)
    status = bus.publisher(keys.MISSION_STATUS)
    answers: list[str] = []
    stop = time.monotonic() + duration_s
    seq = 0

    def now() -> int:
        return time.time_ns()

    requests = [
        (keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=now(), arm=False)),
        (keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=now(), arm=False, force=True)),
        (keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=now(), mode="HOLD")),
        (keys.MISSION_SET, MissionRequest.make(stamp_ns=now(), mission_id="far", coa_radius_m=2.0,
                                               task_power_w=1.0,
                                               waypoints=[Waypoint(x_m=0.0, y_m=0.0),
                                                          Waypoint(x_m=4900.0, y_m=0.0)])),
        (keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=now(), command="abort")),
        (keys.NAV_RESET, NavResetRequest.make(stamp_ns=now(), keep_origin=False)),
    ]
    while time.monotonic() < stop:
        seq += 1
        thrust.put(ThrustCommand.make(stamp_ns=now(), thrust_port_n=FORGED_N[0],
                                      thrust_starboard_n=FORGED_N[1], source="intruder", seq=seq))
        status.put(MissionStatus.make(stamp_ns=now(), state="complete", mission_id=mission_id,
                                      active_leg=0, waypoint_count=2))
        if seq % 25 == 1:
            for spec, req in requests:
                reply = bus.request(spec, req, timeout_s=0.3)
                if reply.accepted or "no reply" not in reply.reason:
                    answers.append(f"{spec.suffix}: accepted={reply.accepted} {reply.reason}")
        time.sleep(0.02)
    return answers


class Watch:
    """What the operator sees: every thrust command, vehicle status and mission status."""

    def __init__(self, bus: Bus) -> None:
        self.thrust: list[ThrustCommand] = []
        self.vehicle: list = []
        self.mission: list[MissionStatus] = []
        bus.subscribe(keys.THRUST, callback=lambda _k, m: self.thrust.append(m))
        bus.subscribe(keys.VEHICLE_STATUS, callback=lambda _k, m: self.vehicle.append(m))
        bus.subscribe(keys.MISSION_STATUS, callback=lambda _k, m: self.mission.append(m))


def test_intruders_move_nothing_and_stop_nothing_on_the_sim_profile(procs, zenoh_env, tmp_path,
                                                                   monkeypatch):
    env = _stack_env(zenoh_env, monkeypatch)
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--scenario",
                      str(short_lake(tmp_path, "intruded")), "--run-dir", str(run)], env, "launcher")
    stack = stack_credentials()
    other = credentials.create(tmp_path / "other-authority", harness=True)
    with Bus.open(VESSEL, identity="operator", credentials=stack) as op:
        w = Watch(op)
        wait_for(lambda: w.mission and w.mission[-1].state == "active", 120,
                 what="the mission active")
        mission_id = w.mission[-1].mission_id
        n_thrust_before, n_vehicle_before, n_mission_before = len(w.thrust), len(w.vehicle), len(w.mission)
        intruders = {
            "no credential": Bus.open(VESSEL, credentials=credentials.NONE),
            "another authority": Bus.open(VESSEL, identity="harness", credentials=other),
            "insider": Bus.open(VESSEL, identity="estimator", credentials=stack),
        }
        answers: dict[str, list[str]] = {}

        def attack(name: str, bus: Bus) -> None:
            answers[name] = _attack(bus, mission_id, 4.0)

        threads = [threading.Thread(target=attack, args=(n, b)) for n, b in intruders.items()]
        for t in threads:
            t.start()
        for t in threads:
            t.join(60)
        for b in intruders.values():
            b.close()
        assert answers == {n: [] for n in intruders}, answers  # no request was even answered

        # Nothing forged arrived at the operator (a process of the stack like any other) ...
        assert len(w.thrust) > n_thrust_before + 20  # the controller kept commanding meanwhile
        assert not [m for m in w.thrust if m.source == "intruder"]
        # ... the vehicle stayed armed in MANUAL, the mission stayed the launcher's and went on.
        during = w.vehicle[n_vehicle_before:]
        assert len(during) >= 2 and all(v.link_ok and v.armed and v.mode == "MANUAL" for v in during), during
        assert {m.mission_id for m in w.mission[n_mission_before:]} == {mission_id}
        assert la.poll() is None, procs.log(la)  # the forged "complete" stopped nothing
        assert w.mission[-1].state == "active"

        # The operator's own requests are answered.
        for command in ("pause", "resume"):
            reply = op.request(keys.MISSION_COMMAND, MissionCommand.make(stamp_ns=time.time_ns(),
                                                                         command=command), timeout_s=5)
            assert reply.accepted, (command, reply.reason)

        # Every attack was counted where it was refused, and `seaway health` shows it. A count is
        # current within a second on a quiet machine; once (CI beside a study on the 2 cores) the
        # link refusals were not yet in 1.5 s after the attack, so ask until every count is in
        # (the deadline only bounds a failure: the counts come within seconds, the mission lasts ~25 s).
        insider = {  # reporter, what the insider (the estimator's certificate) did
            ("vehicle_io", "put", "ctrl/thrust"), ("recorder", "put", "ctrl/thrust"),
            ("recorder", "put", "mission/status"), ("launcher", "put", "mission/status"),
            ("vehicle_io", "query", "vehicle/arm"), ("vehicle_io", "query", "vehicle/mode"),
            ("controller", "query", "mission/set"), ("controller", "query", "mission/command"),
            ("estimator", "query", "nav/reset")}
        deadline = time.monotonic() + 30.0
        while True:
            hp = subprocess.run(
                [sys.executable, "-m", "seaway.tools.cli", "health", "--json", "--wait", "0.5"],
                capture_output=True, text=True, check=False, env=env)
            # (Once, beside a CPU burner, it exited 2 and check=True hid why: say what it said.)
            assert hp.returncode == 0, f"seaway health exited {hp.returncode}: {hp.stderr[-2000:]}"
            health = json.loads(hp.stdout)
            counts = {(r["identity"], c["identity"], c["action"], c["key"].split("/", 2)[-1]): c["count"]
                      for r in health["refusals"] for c in r["counts"]}
            missing = {t for t in insider if counts.get((t[0], "estimator", t[1], t[2]), 0) < 1}
            # The two without a certificate of the stack are refused at the link, by the rendezvous.
            links = sum(c["count"] for r in health["refusals"] for c in r["counts"]
                        if c["identity"] == "unauthenticated" and c["action"] == "connect")
            if (not missing and links >= 2) or time.monotonic() > deadline:
                break
            time.sleep(1.0)
        assert not missing, (missing, counts)
        assert counts[("vehicle_io", "estimator", "put", "ctrl/thrust")] > 100  # 50 Hz for 4 s
        assert links >= 2, (health, procs.log(la)[-4000:])
        # The operator's requests were not refused anywhere.
        assert not [k for k in counts if k[1] == "operator"], counts
        la.wait(180)
    out = procs.log(la)
    assert la.returncode == 0 and "mission complete" in out, out
    # The whole run was MAVLink-signed (the sim profile's key, made by the launcher for the run).
    for service in ("sim", "vehicle_io"):
        assert "MAVLink signing on" in (run / "logs" / f"{service}.log").read_text(), service
    # The recorder is a receiver too: the recording holds no forged message, and it holds the
    # refusal reports (with their schema).
    files = open_paths([run])
    messages = list(iter_messages(files))
    forged = [m for m in messages if m.topic.endswith("/ctrl/thrust") and b'"intruder"' in m.data]
    assert not forged
    reports = [m for m in messages if m.topic == keys.refusals_key(VESSEL, "vehicle_io")]
    assert reports and b'"estimator"' in reports[-1].data


def test_a_forging_insider_changes_nothing_in_lockstep(procs, zenoh_env, tmp_path, monkeypatch):
    """Lockstep: an insider's thrust commands, stamped for the coming periods, are never applied:
    the run's energy equals an undisturbed run's."""
    env = _stack_env(zenoh_env, monkeypatch)
    results = {}
    for name, attack in (("quiet", False), ("attacked", True)):
        run = tmp_path / name
        # NMPC: condition #1 in 36 s of simulated time (CC-EMPC's 333 s would prove no more).
        la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim-batch", "--scenario",
                          "paper-c1", "--controller", "nmpc", "--run-dir", str(run)], env,
                         f"launcher-{name}")
        if attack:
            stack = stack_credentials()
            # The operator watches from its own session: a session hears its own publications.
            with (Bus.open(VESSEL, identity="estimator", credentials=stack) as insider,
                  Bus.open(VESSEL, identity="operator", credentials=stack) as op):
                clock = Watch(op)
                forged = insider.publisher(keys.THRUST, lockstep=True)
                ticks: list[int] = []
                insider.subscribe(keys.SIM_CLOCK,
                                  callback=lambda _k, m, ticks=ticks: ticks.append(m.stamp_ns))
                deadline = time.monotonic() + 60
                sent = 0
                while la.poll() is None and time.monotonic() < deadline:
                    if ticks:
                        t = ticks[-1]
                        for k in range(1, 4):  # this period and the next ones, ahead of the controller
                            forged.put(ThrustCommand.make(stamp_ns=t + k * 100_000_000,
                                                          thrust_port_n=75.0, thrust_starboard_n=-75.0,
                                                          source="intruder", seq=sent))
                            sent += 1
                    time.sleep(0.002)
                assert sent > 100
                assert not [m for m in clock.thrust if m.source == "intruder"]
        la.wait(120)
        assert la.returncode == 0, procs.log(la)
        out = subprocess.run([sys.executable, "-m", "seaway.tools.cli", "report", str(run), "--json",
                              "--no-plots"], capture_output=True, text=True, check=True, env=env).stdout
        results[name] = json.loads(out)["metrics"]["energy_j"]
        # The recorder names every forged publication, also in lockstep, and records its count.
        reports = [Refusals.decode(m.data) for m in iter_messages(open_paths([run]))
                   if m.topic == keys.refusals_key(VESSEL, "recorder")]
        forged = sum(c.count for r in reports[-1:] for c in r.counts
                     if (c.identity, c.action, c.key) == ("estimator", "put", keys.THRUST.key(VESSEL)))
        assert (forged > 100) if attack else (not reports or reports[-1].total == 0), reports[-1:]
    assert results["attacked"] == pytest.approx(results["quiet"], rel=1e-6), results


def _mission_ids(run: Path) -> set[str]:
    ids = set()
    for m in iter_messages(open_paths([run])):
        if m.topic.endswith("/mission/status"):
            ids.add(json.loads(m.data)["mission_id"] or "(idle)")
    return ids


def test_two_stacks_on_one_machine_never_mix(procs, zenoh_env, tmp_path, monkeypatch):
    """Same rendezvous: the second launch refuses, naming the first. Different rendezvous: both run
    their missions to the end, each recording only its own (the vessel name is the same)."""
    from tests.conftest import free_port

    env = _stack_env(zenoh_env, monkeypatch)
    launch = [sys.executable, "-m", "seaway.tools.cli", "launch", "sim-batch"]
    a = procs.start([*launch, "--scenario", "paper-c1", "--stay", "--run-dir", str(tmp_path / "a")],
                    env, "launcher-a")
    entry = wait_for(lambda: stacks.lookup(env["SEAWAY_ZENOH_RENDEZVOUS"]), 30, what="stack a registered")
    second = subprocess.run([*launch, "--scenario", "paper-c2", "--run-dir", str(tmp_path / "b0")],
                            env=env, capture_output=True, text=True, timeout=60)
    assert second.returncode == 2, second.stdout + second.stderr
    assert (f"another Seaway stack runs on {env['SEAWAY_ZENOH_RENDEZVOUS']}" in second.stderr
            and f"launcher pid {entry.pid}" in second.stderr and "sim-batch" in second.stderr), second.stderr
    assert not (tmp_path / "b0" / "recording.mcap").exists()
    a.terminate()
    a.wait(30)

    # Different rendezvous ports, both at once, each with the credentials its launcher made.
    runs = {}
    for name, scenario in (("c1", "paper-c1"), ("c2", "paper-c2")):
        e = dict(env, SEAWAY_ZENOH_RENDEZVOUS=f"tcp/127.0.0.1:{free_port()}")
        runs[name] = (procs.start([*launch, "--scenario", scenario, "--controller", "nmpc",  # short
                                   "--run-dir", str(tmp_path / name)], e, f"launcher-{name}"), scenario)
    for p, _ in runs.values():
        p.wait(180)
        assert p.returncode == 0, procs.log(p)
    for name, (_, scenario) in runs.items():
        ids = _mission_ids(tmp_path / name)
        assert ids <= {scenario, "(idle)"} and scenario in ids, (name, ids)  # none of the other stack


def test_two_stacks_whose_run_folders_share_a_name_keep_their_own_credentials(procs, zenoh_env,
                                                                              tmp_path, monkeypatch):
    """Two studies at once run stacks whose run folders have the same names. Their launchers made
    their credentials in one folder of the stacks registry, named after the run, and the first to
    stop removed it: the other's next restarted process could not open its session ("credentials
    folder ... does not exist", ten times, then failed). Each launch's files now carry its pid."""
    from tests.conftest import free_port

    env = _stack_env(zenoh_env, monkeypatch)
    launch = [sys.executable, "-m", "seaway.tools.cli", "launch", "sim-batch", "--scenario",
              "paper-c1", "--controller", "nmpc"]
    env_b = dict(env, SEAWAY_ZENOH_RENDEZVOUS=f"tcp/127.0.0.1:{free_port()}")
    b = procs.start([*launch, "--stay", "--run-dir", str(tmp_path / "b" / "run")], env_b, "launcher-b")
    entry = wait_for(lambda: stacks.lookup(env_b["SEAWAY_ZENOH_RENDEZVOUS"]), 60,
                     what="stack b registered")
    a = procs.start([*launch, "--run-dir", str(tmp_path / "a" / "run")],
                    dict(env, SEAWAY_ZENOH_RENDEZVOUS=f"tcp/127.0.0.1:{free_port()}"), "launcher-a")
    a.wait(180)
    assert a.returncode == 0, procs.log(a)
    assert Path(entry.credentials).is_dir(), "stack a's stop removed stack b's credentials"
    # b's recorder killed: the launcher restarts it, with b's credentials.
    log = tmp_path / "b" / "run" / "logs" / "recorder.log"
    pid = int(subprocess.run(["pgrep", "-f", f"seaway-recorder .*{tmp_path / 'b' / 'run'}"],
                             capture_output=True, text=True, check=True).stdout.split()[0])
    os.kill(pid, signal.SIGKILL)
    wait_for(lambda: log.read_text().count("recorder ready on vessel") == 2, 60,
             what="b's recorder restarted and ready")
    assert "does not exist" not in log.read_text()
    b.send_signal(signal.SIGINT)
    b.wait(60)
    assert b.returncode == 0, procs.log(b)
    assert not Path(entry.credentials).exists()  # removed by its own launcher
