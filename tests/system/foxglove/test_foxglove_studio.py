"""A recording in Foxglove Studio itself (#18): a lake run of the real stack opens in Foxglove Studio
1.48 (``studio.py``: its web app in Debian's chromium) with the shipped layout, and Foxglove reports no
problem: every channel's schema is one it reads (a JSON Schema with a nullable field used to fail
its whole topic, and with it the cross-track and energy plots), the layout's panels are there and
the log panel shows the run's log lines. And the check bites: a channel with pydantic's own schema
of a message (``anyOf`` with null) is reported as Foxglove's problem.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.writer import Writer
from seaway.contract import keys
from seaway.contract.messages import StateEstimate

from tests.system.foxglove import studio

pytestmark = [pytest.mark.system, pytest.mark.slow]
BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def installed() -> Path:
    try:
        return studio.install()
    except studio.StudioUnavailableError as err:
        pytest.skip(str(err))


@pytest.mark.timeout(600)
def test_a_lake_run_opens_in_foxglove_studio_without_a_problem(tmp_path, zenoh_env, installed) -> None:
    run_dir = tmp_path / "lake"
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", "lake",
                          "--run-dir", str(run_dir)], env=zenoh_env,
                         capture_output=True, text=True, timeout=300, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    view = studio.open_recording(run_dir / "recording.mcap", screenshot=tmp_path / "studio.png")
    assert view.problems == []
    missing = [t for t in studio.layout_titles() if t not in view.text and not t.startswith("Log")]
    assert missing == []
    topics = set(view.topics())
    for topic in ("foxglove/log", "foxglove/vessel1/mission", "foxglove/vessel1/scene/prediction",
                  "foxglove/vessel1/tf/body", "foxglove/vessel1/nav-state",
                  keys.MISSION_STATUS.key("vessel1"), keys.NAV_STATE.key("vessel1"),
                  keys.VEHICLE_BATTERY.key("vessel1")):
        assert topic in topics, topic
    assert "INFO][" in view.text  # the log panel shows rows: messages reached the panels
    assert (tmp_path / "studio.png").stat().st_size > 50_000


@pytest.mark.timeout(300)
def test_a_schema_foxglove_cannot_read_is_reported(tmp_path, installed) -> None:
    # pydantic's schema of StateEstimate, as the recorder wrote it before the Foxglove form.
    path = tmp_path / "raw-schema.mcap"
    est = StateEstimate(stamp_ns=1_000_000_000, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.0, y_m=0.0,
                        psi_rad=0.0)
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema(StateEstimate.SCHEMA, "jsonschema",
                                json.dumps(StateEstimate.model_json_schema()).encode())
        cid = w.register_channel(keys.NAV_STATE.key("vessel1"), "json", sid)
        for i in range(3):
            w.add_message(cid, log_time=(i + 1) * 10**9, publish_time=(i + 1) * 10**9,
                          data=est.encode(), sequence=i)
        w.finish()
    view = studio.open_recording(path, wait_for=None)
    assert any("covariance" in p for p in view.problems), view.problems
