"""The two identification flights on firmware (ArduPilot Rover SITL and PX4 SITL), flown at the
same time: each is some 450 s of real time, almost all of it waiting for the vessel to move, and
the firmwares share nothing (their own instances, ports, rendezvous, run folders). Flown one after
the other they were the longest 16 minutes of the slow suite.

``IdentifyRuns.wait(profile)`` starts every flight the session's selected tests will ask for (so a
run of one test flies one), then waits for the one asked for: (run folder, stdout, log tail).
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from tests.conftest import REPO, free_port

BIN = Path(sys.executable).parent
PROFILES = REPO / "deploy" / "profiles"
TESTS_OF = {
    "identify-ardupilot": "test_identify_flies_the_manoeuvre_on_ardupilot_sitl_and_fits_its_boat",
    "identify-px4": "test_identify_flies_the_manoeuvre_on_px4_sitl_and_fits_its_rover",
}


@dataclass
class Flight:
    run_dir: Path
    proc: subprocess.Popen
    out: Path


@dataclass
class IdentifyRuns:
    """Identification flights of one session, each started once (``wait``)."""

    tmp: Path
    selected: set[str]  # the test names the session will run
    profile_for: dict[str, object] = field(default_factory=dict)  # name -> callable(tmp) -> profile
    flights: dict[str, Flight] = field(default_factory=dict)

    def _start(self, name: str) -> None:
        make_profile = self.profile_for[name]
        folder = self.tmp / name
        folder.mkdir(parents=True, exist_ok=True)
        profile = make_profile(folder)  # type: ignore[operator]
        env = dict(os.environ, PYTHONUNBUFFERED="1",
                   SEAWAY_ZENOH_RENDEZVOUS=f"tcp/127.0.0.1:{free_port()}",
                   SEAWAY_STACKS_DIR=str(folder / "stacks"))
        env.pop("SEAWAY_ZENOH_CONFIG", None)  # the launcher makes its stack's credentials
        for k in ("SEAWAY_CREDENTIALS", "SEAWAY_IDENTITY"):
            env.pop(k, None)
        out = folder / "launch.out"
        run_dir = folder / "run"
        with open(out, "wb") as sink:
            proc = subprocess.Popen([str(BIN / "seaway"), "launch", str(profile), "--run-dir",
                                     str(run_dir)], env=env, stdout=sink,
                                    stderr=subprocess.STDOUT, start_new_session=True)
        self.flights[name] = Flight(run_dir, proc, out)

    def wait(self, name: str, timeout_s: float) -> tuple[Path, str, str]:
        """Start every flight a selected test needs (``name`` at least), then wait for ``name``'s
        launch to end; it must end well: (run folder, its output, the tail for messages)."""
        for other, test in TESTS_OF.items():
            if other not in self.flights and other in self.profile_for and (
                    other == name or test in self.selected):
                self._start(other)
        f = self.flights[name]
        deadline = time.monotonic() + timeout_s
        while f.proc.poll() is None and time.monotonic() < deadline:
            time.sleep(1.0)
        if f.proc.poll() is None:
            _kill(f.proc)
        text = f.out.read_text(errors="replace")
        log = text[-7000:]
        assert f.proc.returncode == 0, log
        return f.run_dir, text, log

    def stop_all(self) -> None:
        for f in self.flights.values():
            _kill(f.proc)


def _kill(proc: subprocess.Popen) -> None:
    """The launcher and whatever it left (its session: the firmware, the services)."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(30)


def makers() -> dict[str, object]:
    """How to make each flight's profile, for the firmwares this machine has."""
    from tests.system.vehicle_io import ardupilot_sitl, px4_sitl

    out: dict[str, object] = {}
    if ardupilot_sitl.FIRMWARE is not None and ardupilot_sitl.START is not None \
            and ardupilot_sitl.START.exists():
        def ardupilot(folder: Path) -> Path:
            from tests.system.launch.test_sitl_ardupilot import profile_copy

            return profile_copy("identify-ardupilot", folder, ardupilot_sitl.sitl_instance())

        out["identify-ardupilot"] = ardupilot
    if px4_sitl.PX4_BIN.exists() and (px4_sitl.PX4_DIR / "etc").is_dir():
        out["identify-px4"] = lambda folder: PROFILES / "identify-px4.toml"
    return out
