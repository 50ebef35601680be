"""An upload to a ground station whose disk has no room: a clear answer, and nothing left behind.
The real ``seaway-groundstation`` with its upload folder on a real, small filesystem (a 2 MiB tmpfs
this test mounts; it needs root).

Before: the write's ``OSError`` left the request as a 500 with a traceback in the log.
"""

from __future__ import annotations

import signal
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from mcap.writer import MCAP0_MAGIC

from tests.system.groundstation.helpers import start_groundstation
from tests.unit.groundstation.test_gs_replay import write_run

pytestmark = pytest.mark.system


def upload(base: str, token: str, name: str, data: bytes) -> tuple[int, bytes]:
    req = urllib.request.Request(f"{base}api/recordings/upload?name={name}", data=data, method="POST",
                                 headers={"Content-Type": "application/octet-stream",
                                          "Authorization": f"Bearer {token}"})
    try:
        with urllib.request.urlopen(req, timeout=60) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as err:
        return err.code, err.read()


def test_an_upload_that_finds_no_room_is_507_and_leaves_nothing(procs, zenoh_env, small_disk,
                                                                 tmp_path: Path) -> None:
    config = tmp_path / "groundstation.toml"
    config.write_text(f'upload_dir = "{small_disk}"\n')
    gs, base, token = start_groundstation(procs, zenoh_env, "--config", str(config))

    status, body = upload(base, token, "big.mcap", MCAP0_MAGIC + b"\0" * (3 << 20))  # 3 MiB > 2 MiB
    assert status == 507, (status, body)
    assert b"no room" in body and b"upload_dir" in body
    assert list(small_disk.iterdir()) == [], "what was written of the upload is left on the disk"
    assert gs.poll() is None and "Traceback" not in procs.log(gs)

    # The room it took is free again: a real recording goes in.
    data = (write_run(tmp_path / "src", n=20) / "recording.mcap").read_bytes()
    status, body = upload(base, token, "small.mcap", data)
    assert status == 200, (status, body)
    assert [p.suffix for p in small_disk.iterdir()] == [".mcap"]
    procs.stop(gs, signal.SIGTERM, timeout_s=15)
    assert gs.returncode == 0, procs.log(gs)
