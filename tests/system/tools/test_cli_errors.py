"""Issue 18, item 5: the command line's errors say what exists, against real processes.

``seaway echo`` takes a full key as well as a suffix, and on a vessel nobody publishes it says,
after a short wait, which vessels are on the bus (here: one real estimator of vessel ``lakeboat``)
instead of waiting in silence; an unknown key lists the topics; a missing scenario or vessel file
lists the ones there are."""

from __future__ import annotations

import subprocess
import time

import pytest
from seaway.runtime.credentials import ENV_IDENTITY

from tests.conftest import BIN, REPO, wait_for

pytestmark = pytest.mark.system


def test_echo_says_which_vessels_are_on_the_bus_and_takes_full_keys(zenoh_env, procs) -> None:
    services = dict(zenoh_env)
    services.pop(ENV_IDENTITY)
    est = procs.start([str(BIN / "seaway-estimator"), "--vessel", "lakeboat", "--scenario", "lake"],
                      services, "estimator")
    wait_for(lambda: "READY" in procs.log(est) or "ready" in procs.log(est).lower(), 90,
             interval_s=0.2, what="the estimator's start")
    echo = subprocess.Popen([str(BIN / "seaway"), "echo", "seaway/ghost/nav/state"], env=zenoh_env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        line = ""
        while time.monotonic() < deadline and "vessels seen" not in line:
            line = echo.stderr.readline()
        assert "no service of vessel 'ghost' on the bus; vessels seen: lakeboat" in line, line
        assert echo.poll() is None  # still listening: a vessel may come
    finally:
        echo.terminate()
        echo.wait(30)


def test_echo_refuses_an_unknown_key_listing_the_topics(zenoh_env) -> None:
    for key in ("nav/stat", "seaway/vessel1/nav/stat", "seaway/vessel1"):
        out = subprocess.run([str(BIN / "seaway"), "echo", key], env=zenoh_env, capture_output=True,
                             text=True, timeout=60, check=False)
        assert out.returncode != 0 and "Traceback" not in out.stderr, out.stderr
        assert "nav/state" in out.stderr and "seaway/vessel1/nav/state" in out.stderr, out.stderr


@pytest.mark.parametrize(("args", "what", "folder"), [
    (["launch", "sim-batch", "--scenario", "nope", "--check"], "scenario", "scenarios"),
    (["bench", "model", "--vessel", "nope"], "vessel file", "vessels"),
])
def test_a_missing_scenario_or_vessel_lists_those_there_are(args, what, folder) -> None:
    out = subprocess.run([str(BIN / "seaway"), *args], capture_output=True, text=True, timeout=120,
                         check=False)
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr
    there = ", ".join(sorted(p.stem for p in (REPO / "deploy" / folder).glob("*.toml")))
    assert f"no {what} 'nope' (deploy/{folder}/); there are: {there}" in out.stderr, out.stderr


def test_a_bad_zenoh_runtime_setting_is_named_by_the_launcher_and_a_service(zenoh_env, tmp_path) -> None:
    """``$ZENOH_RUNTIME`` (Zenoh's thread pools; the launcher sets it for lockstep stacks unless the
    user did) that Zenoh cannot read made every process die of a Rust panic; now each names the
    variable and what it takes, and exits 2 before starting anything."""
    env = dict(zenoh_env, ZENOH_RUNTIME="(bogus: 1)")
    launch = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--run-dir",
                             str(tmp_path / "run"), "--no-report"], env=env, capture_output=True,
                            text=True, timeout=120)
    assert launch.returncode == 2, launch.stdout[-2000:] + launch.stderr[-2000:]
    last = launch.stderr.strip().splitlines()[-1]
    assert last.startswith("seaway launch: $ZENOH_RUNTIME='(bogus: 1)' is not a Zenoh runtime setting")
    assert "app, acc, tx, rx, net" in last and "unset it" in last
    assert not list((tmp_path / "run" / "logs").glob("*.log"))  # no process was started
    service = dict(env)
    service.pop(ENV_IDENTITY)
    est = subprocess.run([str(BIN / "seaway-estimator"), "--vessel", "v1"], env=service,
                         capture_output=True, text=True, timeout=120)
    assert est.returncode == 2, est.stderr[-2000:]
    assert "$ZENOH_RUNTIME='(bogus: 1)' is not a Zenoh runtime setting" in est.stderr
