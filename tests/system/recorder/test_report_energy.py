"""``seaway report``'s energy section on a real recording (issue #17 item 5): the recorder process
records a scripted mission whose energy budget (``mission/energy``) predicts the energy to finish
off by a known fraction of what finishing actually takes (``mission_publisher.prediction_bias``),
with a battery that takes the 'warn' decision part way; the report must find those errors, the
decision and its time, the battery and the energy to home, and draw them."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import BIN, wait_for
from tests.system.recorder import mission_publisher as mp

pytestmark = pytest.mark.system
PUBLISHER = str(Path(__file__).parent / "mission_publisher.py")



def test_report_compares_the_budgets_predictions_with_the_energy_used(procs, zenoh_env, tmp_path) -> None:
    out = tmp_path / "run"
    rec = procs.start([str(BIN / "seaway"), "record", "--out", str(out), "--scenario", "paper-c1",
                       "--status-interval", str(mp.STATUS_INTERVAL_S)], zenoh_env, "recorder")
    wait_for(lambda: "READY" in procs.log(rec), 60, what="recorder ready")
    pub = procs.start([sys.executable, PUBLISHER, "--energy"], zenoh_env, "publisher")
    assert pub.wait(120) == 0, procs.log(pub)
    msgs, live = mp.generate(with_energy=True)
    mp.stop_when_written(procs, rec, len(msgs))
    assert rec.returncode == 0, procs.log(rec)
    sent = json.loads([line for line in procs.log(pub).splitlines() if line.startswith("{")][-1])
    assert sent["sent"] == len(msgs)

    rep = subprocess.run([str(BIN / "seaway"), "report", str(out), "--out", str(tmp_path / "rep")],
                         capture_output=True, text=True, timeout=300, env=zenoh_env)
    assert rep.returncode == 0, rep.stderr
    doc = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    m, e = doc["metrics"], doc["energy_budget"]
    assert m["completed"] and m["energy_j"] == pytest.approx(live["energy_j"], rel=1e-9)
    assert e["recorded"] and e["samples"] == sum(1 for k, _ in msgs if k.endswith("/mission/energy"))
    assert e["energy_used_j"] == pytest.approx(live["energy_j"], rel=1e-9)

    # The errors are the ones the publisher put in: at the start, and at the first prediction at or
    # after half the mission's time.
    start_ns, end_ns = live["mission_start_ns"], live["complete_ns"]
    p = e["prediction"]
    assert p["start"]["t_s"] == 0.0
    assert p["start"]["actual_j"] == pytest.approx(live["energy_j"], rel=1e-9)
    assert p["start"]["error_pct"] == pytest.approx(100 * mp.prediction_bias(0.0), abs=1e-6)
    half_ns = start_ns + math.ceil((end_ns - start_ns) / 2 / mp.DT_NS) * mp.DT_NS  # a period's stamp
    assert p["half"]["t_s"] == pytest.approx((half_ns - start_ns) / 1e9, abs=1e-9)
    frac = (half_ns - start_ns) / (end_ns - start_ns)
    assert p["half"]["error_pct"] == pytest.approx(100 * mp.prediction_bias(frac), abs=1e-6)
    assert p["half"]["low_j"] == pytest.approx(0.9 * p["half"]["predicted_j"])
    assert p["half"]["high_j"] == pytest.approx(1.1 * p["half"]["predicted_j"])
    # The bias falls linearly, so the worst of the last half is where a tenth is left.
    tail = start_ns + (end_ns - start_ns) * 0.9
    last = max(t for t in range(start_ns, end_ns, mp.DT_NS) if t <= tail)
    assert p["last_half_max_abs_error_pct"] == pytest.approx(
        100 * abs(mp.prediction_bias((last - start_ns) / (end_ns - start_ns))), abs=1e-6)

    # The decision, the battery, the point of no return and the energy home at the end.
    budget = live["energy_budget"]
    assert e["decision"] == "warn" and e["policy"] == "warn" and e["reason"] == budget["reason"]
    assert e["decided_t_s"] == pytest.approx((budget["decided_ns"] - start_ns) / 1e9, abs=1e-9)
    assert e["battery_remaining_start_j"] == mp.BATTERY_START_J and e["reserve_j"] == mp.RESERVE_J
    assert e["battery_remaining_end_j"] == pytest.approx(mp.BATTERY_START_J - budget["last_used_j"])
    assert e["battery_reported"]["remaining_start_j"] == mp.BATTERY_START_J
    assert e["energy_to_home_end_j"] == pytest.approx(budget["last_home_j"])
    assert [e["no_return_start"]["x_m"], e["no_return_start"]["y_m"]] == pytest.approx(
        list(budget["first_no_return"]))
    # The table says it, and the energy plot has its second panel (a larger picture).
    assert "to finish, predicted at half way" in rep.stdout and "decision" in rep.stdout
    assert f"error {100 * mp.prediction_bias(0.0):+.1f} %" in rep.stdout
    png = (tmp_path / "rep" / "energy.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert int.from_bytes(png[20:24], "big") > 600  # height [px]: two panels (one is 400)
