"""The launcher with real processes: readiness, restart, failure exit code, clean stop, no orphans."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import wait_for

pytestmark = pytest.mark.system
DUMMY = str(Path(__file__).with_name("dummy_service.py"))


def write_profile(tmp: Path, processes: str, extra: str = "") -> Path:
    path = tmp / "profile.toml"
    path.write_text(f'name = "test"\n{extra}\n[backoff]\ninitial_s = 0.2\nmax_restarts = 3\n{processes}')
    return path


def proc(name: str, service: str, args: str = "", **kw: str) -> str:
    extra = "".join(f"{k} = {v}\n" for k, v in kw.items())
    return (f'[[processes]]\nname = "{name}"\nservice = "{service}"\n'
            f'command = ["{sys.executable}", "{DUMMY}", "--service", "{service}"{args}]\n{extra}')


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie is dead for our purpose.
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except FileNotFoundError:
        return False


def survivors(pids: list[int]) -> str:
    """What the processes still alive are doing, for a failure message: state, parent, where each
    thread waits in the kernel (a survivor is rare; this says why without a rerun)."""
    out = []
    for pid in (p for p in pids if alive(p)):
        try:
            status = dict(line.split(":\t", 1) for line in
                          Path(f"/proc/{pid}/status").read_text().splitlines() if ":\t" in line)
            waits = sorted({(t / "wchan").read_text() or "-"
                            for t in Path(f"/proc/{pid}/task").iterdir()})
            cmd = Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " ")[:160]
        except OSError:
            continue  # gone meanwhile
        out.append(f"pid {pid} state {status.get('State', '?')} ppid {status.get('PPid', '?')} "
                   f"SigPnd {status.get('ShdPnd', '?')} threads waiting in {waits}: {cmd}")
    return "; ".join(out) or "none (all gone just now)"


def launch(procs, zenoh_env, profile: Path, tmp: Path):
    return procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", str(profile),
                        "--run-dir", str(tmp / "run"), "--verbose"], zenoh_env, "launcher")


def test_start_restart_and_clean_stop_without_orphans(procs, zenoh_env, tmp_path) -> None:
    marker = tmp_path / "pids"
    m = f', "--marker", "{marker}"'
    profile = write_profile(tmp_path, proc("rec", "recorder", m)
                            + proc("sim", "sim", m + ', "--ready-after", "0.5"', after='["rec"]')
                            + proc("est", "estimator", m + ', "--ignore-sigint"', after='["sim"]',
                                   stop_timeout_s="1.0"))
    la = launch(procs, zenoh_env, profile, tmp_path)
    wait_for(lambda: "all ready" in procs.log(la) and "estimator up pid" in procs.log(la), 20,
             what="all ready")
    log = procs.log(la)
    # Start order with readiness: sim is declared ready only after 0.5 s, and est waits for it.
    assert log.index("recorder up pid") < log.index("sim up pid") < log.index("estimator up pid")
    pids = [int(x) for x in marker.read_text().split()]
    assert len(pids) == 3

    # A process killed from outside is restarted (on-failure) after its back-off.
    os.kill(pids[1], signal.SIGKILL)
    wait_for(lambda: len(marker.read_text().split()) == 4, 10, what="sim restarted")
    assert "sim exited with code -9; restarting" in procs.log(la)

    # Ctrl-C: everything stops within 5 s (est ignores SIGINT and is killed after 1 s), exit 0.
    t = procs.stop(la, signal.SIGINT, timeout_s=8)
    assert t < 5.0, procs.log(la)
    assert la.returncode == 0, procs.log(la)
    all_pids = [int(x) for x in marker.read_text().split()]
    wait_for(lambda: not any(alive(p) for p in all_pids), 2, what="no orphan processes")
    out = procs.log(la)
    assert "est ignored SIGINT for 1 s; SIGKILL" in out
    # The recorder stops last.
    events = (tmp_path / "run" / "events.jsonl").read_text().splitlines()
    stopped = [e for e in events if '"stopped"' in e]
    assert '"rec"' in stopped[-1]
    assert (tmp_path / "run" / "logs" / "sim.log").read_text().count("--- start") == 2


def test_processes_after_the_same_one_start_together(procs, zenoh_env, tmp_path) -> None:
    """``after`` orders a start and nothing more: two processes after the same one start together,
    and one after both starts once both are ready; a stack starts in its longest chain's time, not
    the sum of its processes' start-ups."""
    times = tmp_path / "times"
    t = f', "--times", "{times}"'
    profile = write_profile(tmp_path, proc("rec", "recorder", t)
                            + proc("sim", "sim", t + ', "--ready-after", "2"', after='["rec"]')
                            + proc("est", "estimator", t + ', "--ready-after", "2"', after='["rec"]')
                            + proc("ctl", "controller", t, after='["sim", "est"]'))
    la = launch(procs, zenoh_env, profile, tmp_path)
    wait_for(lambda: "all ready" in procs.log(la), 30, what="all ready")
    at = {tuple(line.split()[:2]): float(line.split()[2]) for line in times.read_text().splitlines()}
    assert at["sim", "start"] > at["recorder", "up"] and at["estimator", "start"] > at["recorder", "up"]
    # Each started before the other was ready (one after the other, the second would start only
    # once the first was up, 2 s later).
    assert at["sim", "start"] < at["estimator", "up"] and at["estimator", "start"] < at["sim", "up"], at
    assert at["controller", "start"] > max(at["sim", "up"], at["estimator", "up"]), at
    procs.stop(la, signal.SIGINT, timeout_s=8)
    assert la.returncode == 0, procs.log(la)


def test_required_failure_gives_nonzero_exit(procs, zenoh_env, tmp_path) -> None:
    profile = write_profile(tmp_path, proc("sim", "sim")
                            + proc("est", "estimator", ', "--exit-after", "0.5", "--code", "3"',
                                   restart='"never"'))
    la = launch(procs, zenoh_env, profile, tmp_path)
    la.wait(20)
    assert la.returncode == 1, procs.log(la)
    assert "required process(es) failed: est" in procs.log(la)


def test_missing_command_and_bad_profile_are_clear(procs, zenoh_env, tmp_path) -> None:
    bad = write_profile(tmp_path, '[[processes]]\nname = "x"\ncommand = ["no-such-seaway-cmd"]\n')
    la = launch(procs, zenoh_env, bad, tmp_path)
    la.wait(20)
    assert la.returncode == 1
    assert "command 'no-such-seaway-cmd' not found" in procs.log(la)
    two = write_profile(tmp_path, proc("a", "estimator") + proc("b", "estimator"))
    la = launch(procs, zenoh_env, two, tmp_path)
    la.wait(20)
    assert la.returncode == 2
    assert "has two producers: 'a' and 'b'" in procs.log(la)


def test_process_that_never_gets_ready_fails_the_start(procs, zenoh_env, tmp_path) -> None:
    profile = write_profile(tmp_path, proc("sim", "sim", ', "--ready-after", "30"',
                                           ready_timeout_s="1.0"))
    t0 = time.monotonic()
    la = launch(procs, zenoh_env, profile, tmp_path)
    la.wait(20)
    assert la.returncode == 1
    assert "'sim' not ready within 1 s" in procs.log(la)
    assert time.monotonic() - t0 < 10


def test_a_launcher_killed_with_sigkill_leaves_no_process_running(procs, zenoh_env, tmp_path):
    """The parent-death signal (setpriv --pdeathsig): nothing of a SIGKILLed launcher survives it,
    processes ignoring SIGINT included (SIGTERM ends them)."""
    marker = tmp_path / "pids"
    m = f', "--marker", "{marker}"'
    profile = write_profile(tmp_path, proc("rec", "recorder", m)
                            + proc("est", "estimator", m + ', "--ignore-sigint"', after='["rec"]'))
    la = launch(procs, zenoh_env, profile, tmp_path)
    wait_for(lambda: "all ready" in procs.log(la), 20, what="all ready")
    pids = [int(x) for x in marker.read_text().split()]
    assert len(pids) == 2 and all(alive(p) for p in pids)
    os.kill(la.pid, signal.SIGKILL)
    deadline = time.monotonic() + 10.0
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(alive(p) for p in pids), f"orphans 10 s after the launcher's SIGKILL: {survivors(pids)}"
    # Failed in CI (2026-11-24) and here (2026-11-28): the dummy's own Python SIGTERM handler set
    # its stop Event while the main thread held that Event's lock in stop.wait(), and waited on it
    # for good. The dummy now stops as the services do (seaway.runtime.service.on_signals); the
    # same handler hung 17 of 30 children looping on stop.wait(0), on_signals 0 of 30.
