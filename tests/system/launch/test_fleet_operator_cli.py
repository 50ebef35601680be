"""The operator's commands against a running fleet (issue #56 item 11), the real launcher and real
Zenoh with stand-in services (``dummy_service.py``): with several vessels running and none named,
``seaway health`` and ``seaway vehicle status`` name them and ask for ``--vessel`` instead of
falling back to the default vessel; ``health`` lists the running launcher; ``echo --vessel '*'``
says whose each line is; and a vessel whose controller took no mission gets no report."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionAccepted, Waypoint
from seaway.runtime.bus import Bus
from seaway.runtime.service import ENV_VESSEL

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system
DUMMY = str(Path(__file__).with_name("dummy_service.py"))


def seaway(env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(BIN / "seaway"), *args], env=env, capture_output=True, text=True, timeout=60, check=False
    )


def test_commands_in_a_fleet_ask_which_vessel_and_say_whose(procs, zenoh_env, tmp_path) -> None:
    env = {k: v for k, v in zenoh_env.items() if k != ENV_VESSEL}
    dummy = f'"{sys.executable}", "{DUMMY}", "--vessel", "{{vessel}}"'
    profile = tmp_path / "fleet.toml"
    profile.write_text(f"""name = "test-fleet"
vessels = ["va", "vb"]
[[processes]]
name = "ctl"
service = "controller"
per_vessel = true
command = [{dummy}, "--service", "controller", "--publish-thrust", "20"]
""")
    run = tmp_path / "run"
    la = procs.launch(env, str(profile), "--run-dir", str(run), "--no-report")
    wait_for(lambda: "all ready" in procs.log(la), 60, what="all ready")

    for args in (["health", "--wait", "0.2"], ["vehicle", "status", "--timeout", "2"]):
        out = seaway(env, *args)
        assert out.returncode == 2, (args, out.stdout, out.stderr)
        assert "va, vb" in out.stderr and "--vessel" in out.stderr, out.stderr

    out = seaway(env, "health", "--vessel", "vb", "--json", "--wait", "0.5")
    assert out.returncode == 0, out.stderr
    health = json.loads(out.stdout)
    assert health["vessel"] == "vb" and {"launcher", "controller"} <= set(health["alive"]), health

    out = seaway(env, "echo", "ctrl/thrust", "--vessel", "*", "--count", "40")
    assert out.returncode == 0, out.stderr
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    assert len(lines) == 40 and {line["vessel"] for line in lines} == {"va", "vb"}, lines[:4]
    assert all(line["message"]["source"] for line in lines)

    # va's controller takes a mission (the operator's, not the launcher's); vb's never does. The
    # stand-in recorders write nothing: each vessel's recording is put in its folder here.
    for v in ("va", "vb"):
        (run / v / "recording.mcap").write_bytes(b"")
    with Bus.open("va") as bus:
        bus.publisher(keys.MISSION_ACCEPTED).put(ACCEPTED)
        time.sleep(1.0)
    assert procs.stop(la, signal.SIGINT, timeout_s=30) < 30
    assert la.returncode == 0, procs.log(la)
    log = procs.log(la)
    va, vb = log.split("\nva:", 1)[1].split("\nvb:", 1)
    assert "report skipped: --no-report" in va and "no report" not in va, log
    assert "no report: vessel vb flew no mission" in vb, log


ACCEPTED = MissionAccepted(
    stamp_ns=1,
    accepted_ns=1,
    mission_id="",
    coa_radius_m=2.0,
    waypoints=[Waypoint(x_m=0, y_m=0), Waypoint(x_m=10, y_m=0)],
    task_power_w=0.5,
    controller="cc-empc",
    predict_disturbance=False,
)
