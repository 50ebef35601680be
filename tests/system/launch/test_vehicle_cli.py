"""``seaway vehicle`` against real processes: the simulated PX4 (``seaway-sim``, real time, MAVLink
on UDP) and vehicle_io, on the test's own rendezvous and MAVLink port.

Every command runs as the ``operator`` identity (what a shore laptop's operator is), in a new
session, so it must also wait for vehicle_io's queryable as ``seaway mission`` waits for the
controller. The vehicle's own status (``vehicle/status``, read by ``seaway vehicle status``) shows
that each accepted request did what it says.
"""

from __future__ import annotations

import json
import socket
import subprocess

import pytest
from seaway.runtime.credentials import ENV_IDENTITY

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system
VESSEL = "vehiclecli"


def udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def vehicle(env: dict[str, str], *args: str, vessel: str = VESSEL,
            timeout: str = "60") -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "seaway"), "vehicle", *args, "--vessel", vessel,
                           "--timeout", timeout], env=env, capture_output=True, text=True,
                          timeout=180, check=False)


def status(env: dict[str, str]) -> dict:
    out = vehicle(env, "status", timeout="30")
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_arm_mode_and_disarm_reach_the_autopilot_and_refusals_say_why(zenoh_env, procs) -> None:
    port = udp_port()
    # The services run as themselves; the commands as the operator (no harness identity).
    services = dict(zenoh_env)
    services.pop(ENV_IDENTITY)
    operator = dict(services)
    procs.start([str(BIN / "seaway-sim"), "--vessel", VESSEL, "--mavlink", f"udpin:127.0.0.1:{port}"],
                services, "sim")
    vio = procs.start([str(BIN / "seaway-vehicle-io"), "--vessel", VESSEL, "--scenario", "lake",
                       "--mavlink", f"udpout:127.0.0.1:{port}"], services, "vehicle_io")

    # vehicle_io refuses commands until it hears the autopilot, as an operator would see.
    wait_for(lambda: status(operator)["link_ok"], 90, interval_s=0.5, what="the autopilot link")
    out = vehicle(operator, "mode", "MANUAL")
    assert out.returncode == 0, out.stderr + procs.log(vio)[-2000:]
    assert out.stdout.startswith("mode MANUAL: accepted"), out.stdout
    wait_for(lambda: status(operator)["mode"] == "MANUAL", 60, interval_s=0.5, what="mode MANUAL")

    out = vehicle(operator, "arm")
    assert out.returncode == 0 and out.stdout.startswith("arm: accepted"), out.stdout + out.stderr
    wait_for(lambda: status(operator)["armed"] is True, 60, interval_s=0.5, what="armed")

    # A mode the autopilot does not have: refused by vehicle_io, naming the ones it has; nothing
    # changes.
    out = vehicle(operator, "mode", "SAIL")
    assert out.returncode == 1, out.stdout + out.stderr
    assert "mode SAIL: REFUSED:" in out.stderr and "MANUAL" in out.stderr and "HOLD" in out.stderr, \
        out.stderr
    now = status(operator)
    assert now["mode"] == "MANUAL" and now["armed"] is True

    out = vehicle(operator, "disarm", "--force")
    assert out.returncode == 0 and out.stdout.startswith("disarm (forced): accepted"), \
        out.stdout + out.stderr
    wait_for(lambda: status(operator)["armed"] is False, 60, interval_s=0.5, what="disarmed")


def test_without_vehicle_io_it_says_none_was_seen_and_bad_lines_exit_2(zenoh_env) -> None:
    out = vehicle(zenoh_env, "arm", vessel="nobody", timeout="2")
    assert out.returncode == 1
    assert "arm: not delivered: no vehicle_io on vessel nobody: its health token did not appear " \
           "within 2 s" in out.stderr, out.stderr
    for args, text in ((("mode",), "mode: name the mode"),
                       (("arm", "HOLD"), "arm takes no argument (got 'HOLD')"),
                       (("mode", "HOLD", "--force"), "--force applies to arm and disarm only"),
                       (("arm", "--timeout", "0"), "argument --timeout: '0' is not a finite number above 0")):
        out = subprocess.run([str(BIN / "seaway"), "vehicle", *args], env=zenoh_env,
                             capture_output=True, text=True, timeout=60, check=False)
        assert out.returncode == 2 and text in out.stderr, (args, out.stderr)
