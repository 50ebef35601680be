"""`seaway identify`'s pure pieces: the manoeuvre, the thrusters, the checks, the fit, the file."""

from __future__ import annotations

import math

import numpy as np
import pytest
from seaway.contract.config import parse_config, read_document
from seaway.contract.messages import GnssFix, ThrustCommand
from seaway.simkit.scenario import SensorNoise
from seaway.vessel.model import VesselParams, load_vessel
from seaway_lab.identify import fit as ft
from seaway_lab.identify import output
from seaway_lab.identify import parameters as params
from seaway_lab.identify import trace as tr
from seaway_lab.identify.manoeuvre import Manoeuvre
from seaway_lab.identify.sim_run import calm_scenario
from seaway_sim.core import SimCore

# -- the manoeuvre ------------------------------------------------------------------------------


def test_the_manoeuvre_rests_ramps_steps_and_turns_both_ways_within_its_level() -> None:
    m = Manoeuvre(level_n=10.0, reverse_level_n=4.0)
    assert m.thrust_n(-1.0) == (0.0, 0.0) and m.thrust_n(m.duration_s + 1) == (0.0, 0.0)
    assert m.thrust_n(1.0) == (0.0, 0.0)  # rest
    # the dead-zone ramp: linear from 0 to 0.3 of the level over 20 s after 3 s of rest
    assert m.thrust_n(13.0) == pytest.approx((1.5, 1.5))
    ts = np.arange(0.0, m.duration_s, 0.1)
    cmd = np.array([m.thrust_n(t) for t in ts])
    assert cmd[:, 0].max() == pytest.approx(10.0) and cmd[:, 0].min() == pytest.approx(-2.0)
    assert cmd.max() <= 10.0 and cmd.min() >= -4.0
    diff = cmd[:, 0] - cmd[:, 1]
    assert (diff > 2.0).sum() * 0.1 > 30 and (diff < -2.0).sum() * 0.1 > 30  # turns both ways
    assert len({round(s, 2) for s in cmd[:, 0][np.abs(diff) < 1e-9]}) >= 10  # many surge levels


def test_a_manoeuvre_refuses_a_level_that_is_not_positive() -> None:
    with pytest.raises(ValueError, match="level_n must be > 0"):
        Manoeuvre(level_n=0.0)
    with pytest.raises(ValueError, match="reverse_level_n must be > 0"):
        Manoeuvre(level_n=5.0, reverse_level_n=-1.0)


# -- the thrusters ------------------------------------------------------------------------------


def test_produced_thrust_applies_the_dead_zone_then_the_lag() -> None:
    cmd = np.array([[5.0, -12.0], [9.99, 10.0]])
    assert params.produced_thrust(cmd, 10.0, 0.0, 0.1).tolist() == [[0.0, -12.0], [0.0, 10.0]]
    step = np.tile([[4.0, 0.0]], (80, 1))
    out = params.produced_thrust(step, 0.0, 0.5, 0.1)
    # the mean over step k of 4 (1 - exp(-t/0.5)): exact for a first-order lag
    k = 9
    exact = 4.0 * (1.0 - 0.5 / 0.1 * (math.exp(-k * 0.1 / 0.5) - math.exp(-(k + 1) * 0.1 / 0.5)))
    assert out[k, 0] == pytest.approx(exact, rel=1e-9)
    assert out[-1, 0] == pytest.approx(4.0, abs=1e-3) and (out[:, 1] == 0).all()


# -- traces and their checks --------------------------------------------------------------------


def _sim_trace(man: Manoeuvre, vessel: VesselParams, noise: SensorNoise, seconds: float | None = None,
               dead_zone: bool = False) -> tr.Trace:
    """The manoeuvre flown on the simulator's core, straight into a trace (no recording)."""
    sim = SimCore(calm_scenario(vessel.name, noise, dead_zone=dead_zone), vessel)
    thrust, gnss, att = [], [], []
    dur = man.duration_s if seconds is None else seconds
    cmd = (0.0, 0.0)
    for k in range(int(dur / 0.1) + 1):
        if k:
            sim.advance(cmd, 100_000_000)
        s = sim.take_samples()
        gnss += [f for f in s.gnss if f is not None]
        att += s.attitude
        cmd = man.thrust_n(k * 0.1)
        thrust.append((sim.stamp_ns, ThrustCommand(stamp_ns=sim.stamp_ns, thrust_port_n=cmd[0],
                                                   thrust_starboard_n=cmd[1])))
    return tr.from_messages(thrust, gnss, att, source="test run")


def test_a_trace_without_a_stream_is_refused_naming_it() -> None:
    fix = GnssFix(stamp_ns=0, lat_rad=0.1, lon_rad=0.1, alt_m=0.0, fix_type=3)
    with pytest.raises(tr.IdentifyError) as err:
        tr.from_messages([], [fix], [], source="x.mcap")
    text = str(err.value)
    assert "x.mcap" in text and "no thrust commands (ctrl/thrust)" in text
    assert "carry no velocity over ground" in text and "no attitude samples" in text


def test_a_short_run_without_turns_or_coasting_is_refused_naming_each_lack() -> None:
    steps_only = Manoeuvre(level_n=10.0, phases=((3.0, 0.2, 0.2, False), (3.0, 0.5, 0.5, False),
                                                 (3.0, 0.8, 0.8, False)))
    t = _sim_trace(steps_only, load_vessel("paper-sim"), SensorNoise())
    bad = tr.problems(t)
    assert any(b.startswith("too short: ") and "at least 60 s" in b for b in bad), bad
    assert any("no turn to starboard" in b for b in bad) and any("no turn to port" in b for b in bad)
    assert any(b.startswith("no coasting") for b in bad)
    assert not any("surge steps" in b for b in bad)  # it has three levels
    with pytest.raises(tr.IdentifyError, match="cannot be used for a fit: too short"):
        tr.check(t)


def test_the_full_manoeuvre_passes_the_checks() -> None:
    t = _sim_trace(Manoeuvre(level_n=10.0), load_vessel("paper-sim"), SensorNoise())
    assert tr.problems(t) == []


# -- the fit --------------------------------------------------------------------------------------


def test_a_noise_free_run_gives_back_the_vessel_and_its_dead_zone() -> None:
    """The fit's structure is exact: without noise it recovers the plant to a fraction of a percent
    (paper-boat at 30 N with its 10 N dead zone enabled)."""
    boat = load_vessel("paper-boat")
    t = _sim_trace(Manoeuvre(level_n=30.0), boat, SensorNoise(gnss_rate_hz=5.0, attitude_rate_hz=20.0),
                   dead_zone=True)
    res = ft.fit(t, boat.arm_m)
    for p in params.PARAMS:
        assert res.params[p].value == pytest.approx(getattr(boat, p), rel=5e-3), p
    # the ramp climbs 0.27 N per 0.1 s tick: the dead zone is found to within a couple of ticks
    assert res.dead_zone_n == pytest.approx(boat.dead_zone_n, abs=1.0)
    assert res.rms_holdout["u_mps"] < 5e-3 and res.rms_holdout["r_radps"] < 5e-3


def test_a_noise_free_run_of_a_vessel_with_friction_gives_back_its_friction() -> None:
    """The friction terms are identifiable: a noise-free run of paper-sim given surge friction
    (2 N sliding, 3 N at rest, on its 10 N thrusters) gives back every term to a fraction of a
    percent; the same run fitted without them leaves residuals a hundred times larger."""
    base = load_vessel("paper-sim")
    eps = float(params.friction_speed_mps(np.array(2.0), np.array(3.0), np.array(base.m11_kg)))
    v = VesselParams.model_validate({**base.model_dump(), "friction_n": 2.0,
                                     "static_friction_n": 3.0, "friction_speed_mps": eps})
    t = _sim_trace(Manoeuvre(level_n=10.0), v, SensorNoise(gnss_rate_hz=5.0, attitude_rate_hz=20.0))
    res = ft.fit(t, v.arm_m, fit_dead_zone=False, fit_friction=True)
    for p in params.PARAMS:
        assert res.params[p].value == pytest.approx(getattr(v, p), rel=5e-3), p
    assert res.friction["friction_n"].value == pytest.approx(2.0, rel=5e-3)
    assert res.friction["static_friction_n"].value == pytest.approx(3.0, rel=2e-2)
    assert res.friction_speed_mps == pytest.approx(eps)
    assert res.rms_holdout["u_mps"] < 1e-4
    plain = ft.fit(t, v.arm_m, fit_dead_zone=False)
    assert plain.rms_holdout["u_mps"] > 100 * res.rms_holdout["u_mps"] and not plain.friction


@pytest.mark.slow  # two fits of a whole manoeuvre, about 30 s
def test_the_arm_scales_m33_and_nr() -> None:
    """What the yaw data fix is m33/l and Nr/l: fitting with another arm scales both by it; the
    masses move only a little, through the small Munk moment (m22 - m11) u v / l."""
    v = load_vessel("paper-sim")
    t = _sim_trace(Manoeuvre(level_n=10.0), v, SensorNoise(gnss_rate_hz=5.0, attitude_rate_hz=20.0))
    a = ft.fit(t, v.arm_m, fit_dead_zone=False)
    b = ft.fit(t, 2.0 * v.arm_m, fit_dead_zone=False)
    assert b.params["m33_kgm2"].value == pytest.approx(2.0 * a.params["m33_kgm2"].value, rel=2e-3)
    assert b.params["nr_kgm2ps"].value == pytest.approx(2.0 * a.params["nr_kgm2ps"].value, rel=2e-3)
    assert b.params["m11_kg"].value == pytest.approx(a.params["m11_kg"].value, rel=2e-2)
    assert a.ratios["m33_over_arm_kgm"] == pytest.approx(v.m33_kgm2 / v.arm_m, rel=5e-3)


def test_a_bad_arm_or_holdout_is_refused() -> None:
    v = load_vessel("paper-sim")
    t = _sim_trace(Manoeuvre(level_n=10.0), v, SensorNoise(), seconds=70.0)
    with pytest.raises(tr.IdentifyError, match="thruster arm must be > 0 m"):
        ft.fit(t, 0.0)
    with pytest.raises(tr.IdentifyError, match=r"holdout fraction must be in \[0, 0.9\)"):
        ft.fit(t, 0.1, holdout_fraction=0.95)


# -- the vessel file ------------------------------------------------------------------------------


def _result(dead_zone_n: float = 1.5) -> ft.FitResult:
    vals = dict(m11_kg=12.0, m22_kg=11.0, m33_kgm2=1.9, xu_kgps=30.0, yv_kgps=45.0, nr_kgm2ps=0.3)
    nan = np.array([])
    return ft.FitResult(
        params={p: ft.Estimate(v, 0.01 * v) for p, v in vals.items()}, arm_m=0.1,
        dead_zone_n=dead_zone_n, dead_zone_profile=[(0.0, 1.0)], lag_s=0.0, current_ne_mps=(0.01, 0.0),
        start=vals, split_s=100.0, rms_fit={"u_mps": 0.05, "v_mps": 0.05, "r_radps": 0.005},
        rms_holdout={"u_mps": 0.05, "v_mps": 0.05, "r_radps": 0.005}, iterations=5, samples=100,
        prediction=ft.Prediction(nan, nan, nan, nan, nan, nan, nan, nan), notes=["a note"])


def test_the_vessel_file_loads_with_the_fit_and_the_base_vessels_bounds(tmp_path) -> None:
    base = load_vessel("paper-boat")
    path = tmp_path / "b.toml"
    path.write_text(output.vessel_toml(_result(), base, "my-boat", "runs/x/recording.mcap"))
    v = parse_config(read_document(path), VesselParams, str(path))
    assert (v.name, v.m11_kg, v.yv_kgps, v.arm_m, v.dead_zone_n) == ("my-boat", 12.0, 45.0, 0.1, 1.5)
    assert (v.thrust_max_n, v.alpha_w_per_n2) == (base.thrust_max_n, base.alpha_w_per_n2)
    assert base.battery is not None and v.battery == base.battery  # the pack is not in the motion
    text = path.read_text()
    assert "+- 0.12 kg (1.00 %)" in text and "# note: a note" in text and "held-out part" in text
    assert not v.has_friction
    with_friction = _result()
    with_friction.friction = {"friction_n": ft.Estimate(4.0, 0.1),
                              "static_friction_n": ft.Estimate(6.0, 0.3)}
    with_friction.friction_speed_mps = 0.35
    path.write_text(output.vessel_toml(with_friction, base, "my-rover", "x.mcap"))
    r = parse_config(read_document(path), VesselParams, str(path))
    assert (r.friction_n, r.static_n, r.friction_speed_mps) == (4.0, 6.0, 0.35)


def test_the_fits_parameter_vector_keeps_every_time_constant_above_the_floor() -> None:
    theta = np.array([2.0, 3.0, 0.01, 1.0, 20.0, 1.0])  # yaw time constant 0.01 s: below the floor
    z, raised = params.z_of(theta)
    assert raised == ["m33_kgm2"]
    back = params.theta_of(z)[0]
    assert back[[0, 1, 3, 4, 5]] == pytest.approx(theta[[0, 1, 3, 4, 5]], rel=1e-12)
    assert back[2] / back[5] == pytest.approx(1.01 * params.TAU_MIN_S)  # raised just above it
    wild = params.theta_of(np.array([[-50.0, -50.0, -50.0, 3.0, -3.0, 0.0]]))[0]
    assert all(wild[i] / wild[i + 3] >= params.TAU_MIN_S for i in range(3))  # any z stays above it
