"""The boat installs what it runs: the onboard services and the shared library, not the simulator,
the laboratory (benchmarks, harnesses, fake autopilot) or the test tools (docs/deployment.md); and
that installation makes a deployment's credentials and runs its router authenticated."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.system
ROOT = Path(__file__).resolve().parents[3]
BOAT_PACKAGES = ("seaway-vehicle-io", "seaway-estimator", "seaway-controller", "seaway-recorder")


def _uv() -> str:
    found = shutil.which("uv") or str(ROOT / ".tools" / "bin" / "uv")
    if not Path(found).exists():
        pytest.skip("uv is not installed (./test installs it into .tools/)")
    return found


def test_boat_install_has_the_onboard_services_and_nothing_else(tmp_path) -> None:
    venv = tmp_path / "boat"
    cmd = [_uv(), "sync", "--locked", "--no-default-groups", "-q"]
    for pkg in BOAT_PACKAGES:
        cmd += ["--package", pkg]
    env = {**os.environ, "UV_PROJECT_ENVIRONMENT": str(venv)}
    out = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    py = venv / "bin" / "python"
    for present in ("seaway.contract.messages", "seaway.runtime.run", "seaway_controller.main",
                    "seaway_estimator.main", "seaway_vehicle_io.main", "seaway_recorder.main"):
        r = subprocess.run([str(py), "-c", f"import {present}"], capture_output=True, text=True)
        assert r.returncode == 0, f"{present}: {r.stderr[-500:]}"
    for absent in ("seaway_lab", "seaway_sim", "pytest"):
        r = subprocess.run([str(py), "-c", f"import {absent}"], capture_output=True, text=True)
        assert r.returncode != 0 and "No module named" in r.stderr, f"{absent} is installed on the boat"
    seaway = str(venv / "bin" / "seaway")
    bench = subprocess.run([seaway, "bench", "--help"], capture_output=True, text=True)
    assert "installed: none" in bench.stdout
    # Authenticated as shipped: the boat's own installation makes the deployment's credentials and
    # its router takes the boat's half with the shipped (mutual TLS) config.
    creds = tmp_path / "creds"
    made = subprocess.run([seaway, "credentials", "create", str(creds), "--deployment", "--boat-host",
                           "192.168.8.2"], capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr[-2000:]
    env = {k: v for k, v in os.environ.items() if not k.startswith(("SEAWAY_ROUTER_", "SEAWAY_ZENOH_"))}
    check = subprocess.run([seaway, "router", "--role", "boat", "--check"], cwd=ROOT, capture_output=True,
                           text=True, timeout=120, env={**env, "SEAWAY_CREDENTIALS": str(creds / "boat")})
    assert check.returncode == 0, check.stderr[-2000:]
    assert f"{creds / 'boat' / 'router.pem'}" in check.stdout and "access control on" in check.stdout
