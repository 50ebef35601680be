"""What a flight on firmware did, for the SITL tests to say when it went wrong: where its thrust
went, read from its recording (steady thrust, spikes, chatter between periods, a fallback, late or
gappy stamps), its services' warnings, and where a launch that did not end stood.

The recording is read with the ``mcap`` package and ``json`` directly, not our recording reader, so
that a fault in the reader cannot hide itself here.
"""

from __future__ import annotations

import json
import os
import signal
import statistics
import subprocess
from itertools import pairwise
from pathlib import Path

import pytest
from seaway.contract import keys

STOP_WAIT_S = 60.0
"""How long a launch interrupted for taking too long gets to stop and write its logs [s]."""


def _q(values: list[float], frac: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(frac * len(s)))] if s else float("nan")


def thrust_diagnostics(recording: Path, start_ns: int, end_ns: int, alpha_w_per_n2: float
                       ) -> dict[str, object]:
    """Thrust and state over [start_ns, end_ns] (the mission's, from the report) [ns]:
    power alpha (T1^2 + T2^2) [W] median, p99 and max with the five largest commands; mean
    |dT| between consecutive commands [N]; time per thrust source [s]; the largest gaps between
    state stamps and between commands [ms], and commands' delay from stamp to recording [ms]."""
    from mcap.reader import make_reader

    thrust_topic, state_topic = keys.THRUST.suffix, keys.NAV_STATE.suffix
    cmds: list[tuple[int, int, dict]] = []  # (stamp, log time, message)
    states: list[tuple[int, dict]] = []
    with recording.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            topic = channel.topic
            if not (topic.endswith(thrust_topic) or topic.endswith(state_topic)):
                continue
            try:
                body = json.loads(message.data)
            except ValueError:
                continue
            stamp = body.get("stamp_ns")
            if not isinstance(stamp, int) or not start_ns <= stamp <= end_ns:
                continue
            if topic.endswith(thrust_topic):
                cmds.append((stamp, message.log_time, body))
            else:
                states.append((stamp, body))
    power = [alpha_w_per_n2 * (b["thrust_port_n"] ** 2 + b["thrust_starboard_n"] ** 2)
             for _, _, b in cmds]
    top = sorted(range(len(cmds)), key=lambda i: -power[i])[:5]
    steps = [abs(b["thrust_port_n"] - a["thrust_port_n"])
             + abs(b["thrust_starboard_n"] - a["thrust_starboard_n"])
             for (_, _, a), (_, _, b) in pairwise(cmds)]
    by_source: dict[str, float] = {}
    for (s0, _, b), (s1, _, _) in zip(cmds, [*cmds[1:], (end_ns, 0, {})], strict=False):
        by_source[b["source"]] = by_source.get(b["source"], 0.0) + (s1 - s0) / 1e9
    state_gaps = [(b - a) / 1e6 for (a, _), (b, _) in pairwise(states)]
    cmd_gaps = [(b - a) / 1e6 for (a, _, _), (b, _, _) in pairwise(cmds)]
    delays = [(log - stamp) / 1e6 for stamp, log, _ in cmds]
    speeds = [(s["u_mps"], abs(s["v_mps"]), abs(s["r_radps"])) for _, s in states]
    return {
        "commands": len(cmds),
        "power_w": {"median": statistics.median(power) if power else None,
                    "p99": _q(power, 0.99), "max": max(power, default=None)},
        "largest": [{"t_s": round((cmds[i][0] - start_ns) / 1e9, 2), "source": cmds[i][2]["source"],
                     "port_n": round(cmds[i][2]["thrust_port_n"], 2),
                     "starboard_n": round(cmds[i][2]["thrust_starboard_n"], 2)} for i in top],
        "mean_step_n": statistics.fmean(steps) if steps else None,
        "seconds_by_source": {k: round(v, 2) for k, v in by_source.items()},
        "state_gap_ms_max": max(state_gaps, default=None),
        "command_gap_ms_max": max(cmd_gaps, default=None),
        "command_delay_ms": {"median": statistics.median(delays) if delays else None,
                             "p99": _q(delays, 0.99), "max": max(delays, default=None)},
        "state_mean": {"u_mps": statistics.fmean(u for u, _, _ in speeds) if speeds else None,
                       "abs_v_mps": statistics.fmean(v for _, v, _ in speeds) if speeds else None,
                       "abs_r_radps": statistics.fmean(r for _, _, r in speeds) if speeds else None},
    }


def warning_lines(run_dir: Path, services: tuple[str, ...] = ("vehicle_io", "estimator", "controller"),
                  limit: int = 40) -> list[str]:
    """The last ``limit`` WARNING and ERROR lines of these services' logs (``run_dir/logs``), each
    cut to 240 characters: the mission's end, where a run that went wrong says why."""
    lines: list[str] = []
    for name in services:
        path = run_dir / "logs" / f"{name}.log"
        if path.exists():
            lines += [line[:240] for line in path.read_text(errors="replace").splitlines()
                      if " WARNING " in line or " ERROR " in line]
    return lines[-limit:]


def own_warnings(run_dir: Path, service: str = "vehicle_io") -> list[str]:
    """``service``'s WARNING and ERROR lines but those quoting the autopilot ("autopilot says:"):
    what Seaway itself warned of. The firmware's own words are its business (ArduPilot says "EKF
    failsafe cleared" at warning severity as its EKF takes GPS)."""
    return [line for line in warning_lines(run_dir, (service,), limit=1000)
            if "autopilot says:" not in line]


def launch_to_end(args: list[str], run_dir: Path, env: dict[str, str], timeout_s: float
                  ) -> subprocess.CompletedProcess[str]:
    """``seaway launch`` (``args``, run folder ``run_dir``) to its end, as ``subprocess.run`` would.

    One that has not ended after ``timeout_s`` is stopped as an operator would stop it (Ctrl-C,
    SIGKILL after ``STOP_WAIT_S``), and the test fails saying where it stood: the last of its output
    (its status line comes every 5 s) and its services' warnings. A bare timeout would say nothing:
    everything the launcher printed is lost with it."""
    proc = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=STOP_WAIT_S)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, err = proc.communicate()
        pytest.fail(f"seaway launch had not ended after {timeout_s:g} s; interrupted (exit "
                    f"{proc.returncode}). Its output:\n{out[-6000:]}\nIts errors:\n{err[-4000:]}\n"
                    "Its services' warnings:\n" + "\n".join(warning_lines(run_dir)))
    return subprocess.CompletedProcess(args, proc.returncode, out, err)
