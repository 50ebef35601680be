"""`seaway identify` as a user runs it: the manoeuvre flown on the simulator with realistic sensor
noise and recorded, then fitted from the recording; and a recording that cannot support a fit is
refused naming what it lacks. Real processes (the `seaway` command), real MCAP files."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from seaway.vessel.model import load_vessel
from seaway_lab.identify.manoeuvre import Manoeuvre
from seaway_lab.identify.parameters import PARAMS
from seaway_lab.identify.sim_run import calm_scenario, fly_in_sim

from tests.conftest import BIN, REPO

pytestmark = pytest.mark.system
SEAWAY = str(BIN / "seaway")


def _seaway(*args: str, timeout_s: float = 240.0) -> subprocess.CompletedProcess:
    return subprocess.run([SEAWAY, *args], cwd=REPO, capture_output=True, text=True, timeout=timeout_s)


@pytest.mark.timeout(300)
def test_identify_recovers_the_sim_boat_within_5_percent_from_a_noisy_run(tmp_path: Path) -> None:
    """paper-boat (the paper's boat as built: 75 N thrusters, 10 N dead zone) flown at 30 N with
    GNSS 0.3 m / 0.05 m/s at 5 Hz, heading 1 deg and yaw rate 0.005 rad/s at 20 Hz."""
    rec = tmp_path / "boat.mcap"
    run = _seaway("identify", "run", "--sim", "--vessel", "paper-boat", "--dead-zone",
                  "--level-n", "30", "--out", str(rec))
    assert run.returncode == 0, run.stderr
    assert rec.is_file() and "flew the manoeuvre" in run.stdout
    out = tmp_path / "fitted.toml"
    fit = _seaway("identify", "fit", str(rec), "--base", "paper-boat", "--compare", "paper-boat",
                  "--name", "boat-fit", "--out", str(out), "--plot", str(tmp_path / "fit.png"), "--json")
    assert fit.returncode == 0, fit.stderr
    res = json.loads(fit.stdout)
    truth = load_vessel("paper-boat")
    for p in PARAMS:
        assert abs(res["errors_pct"][p]) < 5.0, (p, res["params"][p], getattr(truth, p))
        # and the fit knows its precision: its standard error is below the 5 % asked
        assert res["params"][p]["std"] < 0.05 * res["params"][p]["value"], p
    assert res["dead_zone_n"] == pytest.approx(truth.dead_zone_n, rel=0.05)
    fitted = load_vessel(out)  # the file loads as any vessel file does
    assert fitted.name == "boat-fit" and fitted.arm_m == truth.arm_m
    assert fitted.thrust_max_n == truth.thrust_max_n
    # the held-out tail is predicted to the sensors' noise (0.05 m/s, 0.005 rad/s)
    assert res["rms_holdout"]["u_mps"] < 0.07 and res["rms_holdout"]["r_radps"] < 0.007
    assert (tmp_path / "fit.png").stat().st_size > 10_000


@pytest.mark.timeout(120)
def test_a_recording_too_short_and_without_turns_is_refused_naming_what_is_missing(tmp_path: Path) -> None:
    v = load_vessel("paper-sim")
    from seaway_lab.closed_loop import REALISTIC_NOISE

    steps = Manoeuvre(level_n=8.0, phases=((4.0, 0.3, 0.3, False), (4.0, 0.7, 0.7, False),
                                           (4.0, 1.0, 1.0, False), (4.0, 0.0, 0.0, False)))
    rec = fly_in_sim(calm_scenario("paper-sim", REALISTIC_NOISE), v, steps, tmp_path / "short.mcap").path
    fit = _seaway("identify", "fit", str(rec), "--base", "paper-sim")
    assert fit.returncode == 1, (fit.stdout, fit.stderr)
    err = fit.stderr
    assert "cannot be used for a fit" in err and "too short: 16.0 s" in err and "at least 60 s" in err
    assert "no turn to starboard" in err and "no turn to port" in err
    assert "surge steps" not in err.split("cannot be used")[1].split("(fly")[0]  # it has 3 levels
    assert not (tmp_path / "short.vessel.toml").exists()


def test_a_recording_that_is_not_there_or_not_a_recording_is_a_usage_error(tmp_path: Path) -> None:
    missing = _seaway("identify", "fit", str(tmp_path / "none.mcap"))
    assert missing.returncode == 2 and "no such file or folder" in missing.stderr
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap")
    res = _seaway("identify", "fit", str(bad))
    assert res.returncode == 2 and "bad.mcap" in res.stderr and "Traceback" not in res.stderr
    run = _seaway("identify", "run")
    assert run.returncode == 2 and "seaway identify fly" in run.stderr
