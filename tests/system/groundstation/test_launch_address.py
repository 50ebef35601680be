"""``./run``'s launcher (``seaway launch sim``, what ``./run`` execs) prints the ground station's page
address once the stack is ready, the page and its API answer there with the token it carries, and
the token is written nowhere in the run folder but the owner-only address file: not in the logs (the
ground station's own output is ``logs/groundstation.log``), the events, nor the recording. The
stack's MAVLink is on a port of its own: it arms with PX4 SITL's usual port held by someone else."""

from __future__ import annotations

import contextlib
import json
import re
import signal
import socket
import sys
from pathlib import Path

import pytest

from tests.conftest import wait_for
from tests.system.groundstation.helpers import http_raw as http

pytestmark = pytest.mark.system
PX4_API_PORT = 14580
"""PX4 SITL's API-link port, where a simulated PX4 listens by default: another stack, a SITL or a
test may hold it; the sim profile must not need it."""
PAGE_LINE = re.compile(r"^ground station: (http://127\.0\.0\.1:(\d+)/)#token=(\S+)$", re.MULTILINE)


@pytest.fixture
def px4_port_held():
    """PX4 SITL's API-link port held for the test (if nobody holds it already)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        with contextlib.suppress(OSError):  # already held elsewhere: as good for this test
            held.bind(("127.0.0.1", PX4_API_PORT))
        yield


def test_the_launcher_prints_the_page_address_and_the_token_stays_out_of_the_run(
        procs, zenoh_env, tmp_path, px4_port_held) -> None:
    from seaway.recording.reader import iter_messages, read_info

    run = tmp_path / "run"
    launcher = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--run-dir",
                            str(run), "--no-mission", "--stay"], zenoh_env, "launcher")

    def printed() -> re.Match | None:
        if launcher.poll() is not None:
            pytest.fail(f"the launcher exited ({launcher.returncode}):\n{procs.log(launcher)[-3000:]}")
        return PAGE_LINE.search(procs.log(launcher))

    line = wait_for(printed, 240, interval_s=0.2, what="the launcher's 'ground station:' line")
    url, token = line.group(1), line.group(3)
    out = procs.log(launcher)
    assert out.index("all ready in") < line.start(), out
    doc = json.loads((run / "groundstation" / "address.json").read_text())
    assert doc["page"] == f"{url}#token={token}" and doc["url"] == url and doc["token"] == token

    # The page and its API answer at that address; the token it carries commands the vessel.
    status, body = http("GET", url)
    assert status == 200 and b"<html" in body.lower()
    wait_for(lambda: "arm: accepted" in procs.log(launcher), 120, what="the launcher's arming")
    status, body = http("POST", url + "api/vessels/vessel1/mode", {"mode": "MANUAL"})
    assert status == 401, body
    status, body = http("POST", url + "api/vessels/vessel1/mode", {"mode": "MANUAL"}, token=token)
    assert status == 200 and json.loads(body)["accepted"], body

    assert procs.stop(launcher, signal.SIGINT, timeout_s=180) < 180
    assert launcher.returncode == 0, procs.log(launcher)[-3000:]
    gs_log = (run / "logs" / "groundstation.log").read_text()
    assert f"groundstation: {url} the operator token is in {run / 'groundstation' / 'address.json'}" \
        in gs_log, gs_log

    # Nowhere in the run folder but the address file: logs, events, run description, the ground
    # station's requests journal, the report; the recording read message by message (it is
    # compressed), with its attachments and metadata.
    secret = token.encode()
    looked = []
    for path in sorted(p for p in run.rglob("*") if p.is_file()):
        if path == run / "groundstation" / "address.json":
            continue
        if path.suffix == ".mcap":
            info = read_info([path])
            assert not any(secret in m.data for m in iter_messages([path])), path
            assert not any(secret in a for a in info.attachments.values()), path
            assert secret not in json.dumps(info.metadata).encode(), path
        else:
            assert secret not in path.read_bytes(), path
        looked.append(path.relative_to(run))
    assert Path("logs/groundstation.log") in looked and Path("events.jsonl") in looked
    assert Path("recording.mcap") in looked and Path("groundstation/requests.jsonl") in looked
