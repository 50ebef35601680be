"""Re-record the replay regression goldens: ``./test tests/replay --regen`` (and nothing else) does.

Each golden is a real recording of the real stack in lockstep (sim, estimator, controller as
separate processes on a private Zenoh port, the recorder keeping only the keys the replay tests
read), cut after ``SECONDS`` of simulated time. Commit the new files with a message saying why the
outputs changed.
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from seaway.contract import keys
from seaway.runtime import credentials
from seaway.runtime.bus import Bus

DATA = Path(__file__).with_name("data")
VESSEL = "replay1"
RECORDED = ("sensors/gnss", "sensors/attitude", "sim/clock", "nav/state", "nav/origin", "ctrl/thrust",
            "sim/truth", "lockstep/sim")
GOLDENS = {"lake-30s": ("lake", 30.0)}  # name: (scenario, simulated seconds)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def record(name: str, scenario: str, seconds: float) -> Path:
    """Run the lockstep stack on ``scenario`` for ``seconds`` of sim time; the recording's path."""
    tmp = Path(tempfile.mkdtemp(prefix="seaway-regen-"))
    # The stack's own credentials (no launcher makes them here): every service its own identity,
    # this process the harness, as the system tests run (tests/conftest.py's zenoh_env).
    folder = credentials.create(tmp / "credentials", harness=True).folder
    env = dict(os.environ, SEAWAY_ZENOH_RENDEZVOUS=f"tcp/127.0.0.1:{_free_port()}", PYTHONUNBUFFERED="1")
    env[credentials.ENV_CREDENTIALS], env[credentials.ENV_IDENTITY] = str(folder), "harness"
    for name_ in ("SEAWAY_ZENOH_RENDEZVOUS", credentials.ENV_CREDENTIALS, credentials.ENV_IDENTITY):
        os.environ[name_] = env[name_]
    bin_ = Path(sys.executable).parent
    out = tmp / f"{name}.mcap"
    common = ["--vessel", VESSEL]
    key_args = [a for k in RECORDED for a in ("--key-expr", f"seaway/{VESSEL}/{k}")]
    cmds = [
        [bin_ / "seaway-recorder", *common, "--out", str(out), "--scenario", scenario, *key_args,
         "--no-foxglove", "--lockstep"],
        [bin_ / "seaway-sim", *common, "--scenario", scenario, "--lockstep"],
        [bin_ / "seaway-estimator", *common, "--scenario", scenario, "--lockstep"],
        [bin_ / "seaway-controller", *common, "--scenario", scenario, "--lockstep"],
    ]
    procs = []
    try:
        with Bus.open(VESSEL) as bus:
            for cmd in cmds:
                procs.append(subprocess.Popen([str(c) for c in cmd], env=env, start_new_session=True,
                                              stdout=open(tmp / f"{Path(cmd[0]).name}.log", "wb"),  # noqa: SIM115
                                              stderr=subprocess.STDOUT))
                time.sleep(1.0)  # the recorder first, then the producers, in data-flow order
            clock = bus.subscribe(keys.SIM_CLOCK, mode="latest")
            deadline = time.monotonic() + 300
            while True:
                tick = clock.get(1.0)
                if tick is not None and tick.stamp_ns >= seconds * 1e9:
                    break
                if time.monotonic() > deadline or any(p.poll() is not None for p in procs):
                    raise RuntimeError(f"regen of {name} did not reach {seconds} s; logs in {tmp}")
        for p in reversed(procs):  # the recorder last, so it sees everything
            p.send_signal(signal.SIGINT)
            p.wait(20)
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
    DATA.mkdir(exist_ok=True)
    dest = DATA / f"{name}.mcap"
    shutil.copyfile(out, dest)
    return dest


def regen_all() -> list[Path]:
    return [record(name, sc, secs) for name, (sc, secs) in GOLDENS.items()]


if __name__ == "__main__":
    for p in regen_all():
        print(f"wrote {p} ({p.stat().st_size / 1024:.0f} KiB)")
