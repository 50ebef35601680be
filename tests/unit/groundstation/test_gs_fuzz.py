"""A bounded fuzz of the ground station's OpenAPI schema (schemathesis): every operation, with and
without the operator token, against the real application served by uvicorn on loopback over the
in-memory bus. A stand-in vessel answers every request (accepting some, refusing others) and a
recording lies in the runs folder, so the requests get past "vessel never seen" and "no such
recording" to the code behind them. No answer may be a server error, and every answer must match
the schema's status codes, content types and bodies (schemathesis's default checks)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.specs.openapi.checks import positive_data_acceptance
from seaway.contract import keys
from seaway.contract.messages import MissionStatus, NavOrigin, Reply, StateEstimate
from seaway.runtime.memory_bus import MemoryHub
from seaway_groundstation.app import create_app
from seaway_groundstation.settings import Settings

from tests.unit.groundstation.live_server import serve
from tests.unit.groundstation.test_gs_replay import write_run

TOKEN = "fuzz-token-0123456789abcdef"
VESSEL = "vessel1"  # the name the schema's examples give
MAX_EXAMPLES = 20
"""Examples per operation and phase: 21 operations, each example sent without and with the token;
about 20 s on a quiet 2-core machine."""
CONTENT_CHECKED = {"/api/vessels/{vessel}/mission/import", "/api/missions/parse", "/api/recordings/upload",
                   "/api/recording", "/api/recording/frames"}
"""Operations whose content the schema cannot fully describe (a mission file, a recording and its
name, a time span): a schema-valid request may still be refused with 422 naming what is wrong, so
"valid data is accepted" is not checked there (everything else is)."""


def _vessel(hub: MemoryHub) -> None:
    """vessel1's services: every request answered, a mission refused when it has many waypoints."""
    bus = hub.bus(VESSEL)
    for service in ("vehicle_io", "controller", "estimator", "sim"):
        bus.declare_alive(service)

    def answer(req: Any) -> Reply:
        if getattr(req, "waypoints", None) is not None and len(req.waypoints) > 50:
            return Reply.refuse(1, "too many waypoints for the test vessel")
        return Reply.accept(1, "done")

    for spec in (keys.VEHICLE_ARM, keys.VEHICLE_MODE, keys.MISSION_SET, keys.MISSION_COMMAND,
                 keys.MISSION_HOME, keys.SIM_SCENARIO):
        bus.queryable(spec, answer)
    bus.publisher(keys.NAV_ORIGIN).put(NavOrigin(stamp_ns=1, lat_rad=0.49, lon_rad=1.97, alt_m=0.0))
    bus.publisher(keys.NAV_STATE).put(StateEstimate(stamp_ns=1, u_mps=1.0, v_mps=0.0, r_radps=0.0,
                                                    x_m=1.0, y_m=2.0, psi_rad=0.0))
    bus.publisher(keys.MISSION_STATUS).put(MissionStatus(stamp_ns=1, state="active", mission_id="m"))


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, dict[str, Any]]]:
    tmp = tmp_path_factory.mktemp("fuzz")
    runs = tmp / "runs"
    write_run(runs / "20260101-120000-sim-lake-cc-empc", n=30)
    hub = MemoryHub()
    _vessel(hub)
    with serve(hub, TOKEN, request_timeout_s=2.0, runs_dir=runs, upload_dir=tmp / "uploads",
               max_upload_bytes=1 << 20, rate_limit_per_s=1e6, rate_limit_burst=1_000_000,
               run_dir=tmp / "run") as served:
        yield f"http://127.0.0.1:{served.port}", served.app.openapi()


# The schema does not depend on the bus or the settings: read it from an application made here.
schema = schemathesis.openapi.from_dict(create_app(MemoryHub().bus("gs"), Settings(token=TOKEN)).openapi())


@schema.parametrize()
@settings(max_examples=MAX_EXAMPLES, deadline=None, derandomize=True,
          suppress_health_check=list(HealthCheck))
def test_no_request_makes_a_server_error(case: Any, served: tuple[str, dict[str, Any]]) -> None:
    base = served[0]
    excluded = [positive_data_acceptance] if case.operation.path in CONTENT_CHECKED else []
    for headers in ({}, {"Authorization": f"Bearer {TOKEN}"}):
        response = case.call_and_validate(base_url=base, headers=headers, excluded_checks=excluded)
        assert response.status_code < 500, (case.method, case.path, response.status_code, response.text[:300])


def test_the_server_survived_the_fuzz(served: tuple[str, dict[str, Any]]) -> None:
    import json
    import urllib.request

    with urllib.request.urlopen(served[0] + "/api/vessels/" + VESSEL, timeout=10) as r:
        assert r.status == 200 and json.loads(r.read())["vessel"] == VESSEL


def test_runs_folder_is_untouched_by_the_fuzz(served: tuple[str, dict[str, Any]],
                                              tmp_path_factory: pytest.TempPathFactory) -> None:
    base = Path(str(tmp_path_factory.getbasetemp()))
    runs = next(base.glob("fuzz*/runs"))
    assert sorted(p.name for p in runs.iterdir()) == ["20260101-120000-sim-lake-cc-empc"]
