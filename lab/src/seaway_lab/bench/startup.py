"""``seaway bench startup``: cold start of a launcher profile until every service is ready.

Runs ``seaway launch PROFILE --no-mission`` as a real subprocess on a private Zenoh rendezvous port,
reads the launcher's own "all ready in X s" (readiness = every health token seen), then stops it with
SIGINT and times the stop as well. The baseline in the same run is the floor of any Seaway process:
a bare interpreter importing ``seaway.runtime.bus`` and opening a Zenoh session. Target: ready in < 5 s.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from seaway.runtime.argtypes import positive_float, positive_int
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.vessel.metrics import median

from seaway_lab.bench.common import BenchResult, bench_credentials, free_rendezvous

TARGET_READY_S = 5.0
_READY = re.compile(r"all ready in ([0-9.]+) s")


def _env() -> dict[str, str]:
    env = dict(os.environ, **bench_credentials())
    env[ENV_RENDEZVOUS] = free_rendezvous()
    env.pop(ENV_CONFIG, None)
    return env


def _one_start(profile: str, timeout_s: float) -> tuple[float, float, float]:
    """(launcher-reported ready s, wall s from spawn to ready, stop s) for one cold start."""
    with tempfile.TemporaryDirectory(prefix="seaway-startup-") as tmp:
        t0 = time.monotonic()
        p = subprocess.Popen([sys.executable, "-m", "seaway.tools.cli", "launch", profile, "--no-mission",
                              "--run-dir", str(Path(tmp) / "run")], env=_env(),
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                             start_new_session=True)
        assert p.stdout is not None
        reported = None
        lines = []
        deadline = time.monotonic() + timeout_s
        for line in p.stdout:
            lines.append(line.rstrip())
            m = _READY.search(line)
            if m:
                reported = float(m.group(1))
                break
            if time.monotonic() > deadline:
                break
        wall = time.monotonic() - t0
        if reported is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
            tail = "\n".join(lines[-15:])
            raise RuntimeError(f"profile {profile!r} did not get ready:\n{tail}")
        t1 = time.monotonic()
        p.send_signal(signal.SIGINT)
        p.communicate(timeout=30)
        return reported, wall, time.monotonic() - t1


def _baseline() -> float:
    code = ("from seaway.runtime.bus import Bus; b = Bus.open('vessel1'); b.declare_alive('sim'); b.close()")
    t0 = time.monotonic()
    subprocess.run([sys.executable, "-c", code], env=_env(), check=True)
    return time.monotonic() - t0


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench startup", description=__doc__.split("\n\n")[0])
    ap.add_argument("--profile", default="sim", help="launcher profile to start (default sim)")
    ap.add_argument("--repeats", type=positive_int, default=3, help="cold starts to time (median)")
    ap.add_argument("--timeout", type=positive_float, default=60.0,
                    help="seconds a start may take before it counts as failed")
    args = ap.parse_args(argv)
    runs = [_one_start(args.profile, args.timeout) for _ in range(args.repeats)]
    base = [_baseline() for _ in range(args.repeats)]
    ready = [r[0] for r in runs]
    res = BenchResult("startup", f"Cold start of profile '{args.profile}' to all services ready "
                                 f"({args.repeats} runs)")
    res.add("ready_median_s", median(ready), f"< {TARGET_READY_S:g}", median(ready) < TARGET_READY_S,
            "launcher: first spawn to last health token")
    res.add("ready_max_s", max(ready), note="worst of the runs")
    res.add("spawn_to_ready_wall_median_s", median([r[1] for r in runs]), note="incl. launcher start")
    res.add("stop_median_s", median([r[2] for r in runs]), "< 5", median([r[2] for r in runs]) < 5,
            "SIGINT to launcher exit")
    res.add("baseline_one_process_s", median(base), note="import seaway + open Zenoh + token")
    res.add("ready_vs_one_process", median(ready) / median(base), note="ratio")
    return res
