"""The launcher running several vessels, with stand-in processes (``dummy_service.py``): each copy of
a per-vessel process is ready by its own vessel's health token and watched on its own vessel's keys,
so a controller that hangs on one vessel is restarted while the same service on the other, which
keeps publishing the same key under its own name, is left alone; and each vessel's run description
and process events are in its own folder."""

from __future__ import annotations

import json
import signal
import sys
from pathlib import Path

import pytest

from tests.conftest import wait_for

pytestmark = pytest.mark.system
DUMMY = str(Path(__file__).with_name("dummy_service.py"))


def test_a_hung_process_of_one_vessel_is_restarted_and_the_other_vessel_left_alone(
        procs, zenoh_env, tmp_path) -> None:
    dummy = f'"{sys.executable}", "{DUMMY}", "--vessel", "{{vessel}}"'
    profile = tmp_path / "fleet.toml"
    profile.write_text(f'''name = "test-fleet"
vessels = ["va", "vb"]
[backoff]
initial_s = 0.2
[[processes]]
name = "rec"
service = "recorder"
per_vessel = true
command = [{dummy}, "--service", "recorder"]
[[processes]]
name = "ctl"
service = "controller"
per_vessel = true
after = ["rec"]
command = [{dummy}, "--service", "controller", "--publish-thrust", "20", "--quiet-after", "3",
           "--quiet-vessel", "vb"]
''')
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", str(profile), "--run-dir",
                      str(run), "--verbose"], zenoh_env, "launcher")
    wait_for(lambda: "all ready" in procs.log(la), 60, what="all ready")
    table = procs.log(la)
    for name in ("rec-va", "rec-vb", "ctl-va", "ctl-vb"):
        assert name in table, table
    assert "vessels va, vb" in table

    # vb's controller stops publishing ctrl/thrust after 3 s while va's goes on: only vb's is hung.
    wait_for(lambda: "ctl-vb is hung: published no ctrl/thrust" in procs.log(la), 60,
             what="ctl-vb found hung")
    wait_for(lambda: (run / "logs" / "ctl-vb.log").read_text().count("--- start") == 2, 30,
             what="ctl-vb restarted")
    assert procs.stop(la, signal.SIGINT, timeout_s=30) < 30
    assert la.returncode == 0, procs.log(la)
    out = procs.log(la)
    assert "ctl-va is hung" not in out
    assert (run / "logs" / "ctl-va.log").read_text().count("--- start") == 1

    for v in ("va", "vb"):
        assert json.loads((run / v / "run.json").read_text())["vessel"] == v
        events = [json.loads(line) for line in (run / v / "events.jsonl").read_text().splitlines()]
        assert {e["process"] for e in events} == {f"rec-{v}", f"ctl-{v}"}, events
        hung = [e for e in events if e["event"] == "hung"]
        assert [e["process"] for e in hung] == (["ctl-vb"] if v == "vb" else []), events
    every = (run / "events.jsonl").read_text()
    assert all(f'"{n}"' in every for n in ("rec-va", "rec-vb", "ctl-va", "ctl-vb"))
