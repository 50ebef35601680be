"""EstimatorCore: initialisation, input guards, gating, dropouts, reset, numerics (pure, no bus)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from seaway.contract.config import ConfigError, Origin, parse_config
from seaway.contract.messages import Attitude, GnssFix, ThrustCommand
from seaway.contract.units import NS_PER_S
from seaway.vessel import model
from seaway.vessel.frames import GeoOrigin, wrap_pi
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore, EstimatorError
from seaway_estimator.kalman import IPSI, IX, IY, NZ

MS = 1_000_000
S = NS_PER_S
ORIGIN = GeoOrigin(math.radians(47.0), math.radians(8.0), 0.0)
FIXED = EstimatorConfig(origin=Origin(lat_deg=47.0, lon_deg=8.0))


def fix(t_ns: int, north: float, east: float, vn: float | None = 0.0, ve: float | None = 0.0,
        fix_type: int = 3, std: float | None = 0.3) -> GnssFix:
    lat, lon, _ = ORIGIN.to_geodetic(north, east, 0.0)
    return GnssFix(stamp_ns=t_ns, lat_rad=lat, lon_rad=lon, alt_m=0.0, fix_type=fix_type,
                   vel_n_mps=vn, vel_e_mps=ve, horizontal_std_m=std)


def att(t_ns: int, psi: float, r: float = 0.0) -> Attitude:
    return Attitude(stamp_ns=t_ns, roll_rad=0.0, pitch_rad=0.0, yaw_rad=wrap_pi(psi), roll_rate_radps=0.0,
                    pitch_rate_radps=0.0, yaw_rate_radps=r)


def started(config: EstimatorConfig = FIXED, psi: float = 0.0) -> EstimatorCore:
    core = EstimatorCore(config)
    core.on_gnss(fix(0, 0.0, 0.0))
    core.on_attitude(att(0, psi))
    assert core.initialised
    return core


def test_initialises_only_with_a_position_and_a_heading_and_fixes_the_origin() -> None:
    core = EstimatorCore()
    assert core.predict_to(0) is None and core.origin is None
    core.on_gnss(fix(0, 3.0, 4.0, fix_type=1))  # no fix: ignored, counted, no origin
    assert core.counters["gnss_no_fix"] == 1 and core.origin is None
    core.on_gnss(fix(100 * MS, 3.0, 4.0, vn=0.5, ve=0.0))
    assert core.origin is not None and core.nav_origin(1) is not None
    assert core.predict_to(100 * MS) is None  # a position but no heading yet
    core.on_attitude(att(120 * MS, math.pi / 2, 0.01))
    est = core.predict_to(120 * MS)
    assert est is not None and est.stamp_ns == 120 * MS
    # The origin is the first good fix, so that fix is at (0, 0); SOG north at heading east is sway.
    assert abs(est.x_m) < 0.02 and abs(est.y_m) < 0.02
    assert est.psi_rad == pytest.approx(math.pi / 2, abs=1e-3)
    assert est.v_mps == pytest.approx(-0.5, abs=0.01) and abs(est.u_mps) < 0.01
    assert len(est.covariance) == NZ * NZ and not est.degraded


def test_non_finite_inputs_are_refused_counted_and_change_nothing() -> None:
    core = started()
    before = core.predict_to(100 * MS)
    bad_fix = GnssFix.model_construct(**{**fix(150 * MS, 1.0, 1.0).model_dump(), "lat_rad": math.nan})
    with pytest.raises(EstimatorError, match=r"GnssFix\.lat_rad"):
        core.on_gnss(bad_fix)
    bad_att = Attitude.model_construct(**{**att(150 * MS, 0.0).model_dump(), "yaw_rad": math.inf})
    with pytest.raises(EstimatorError, match=r"Attitude\.yaw_rad"):
        core.on_attitude(bad_att)
    bad_thrust = ThrustCommand.model_construct(stamp_ns=150 * MS, thrust_port_n=math.nan,
                                               thrust_starboard_n=1.0, source="", seq=0)
    with pytest.raises(EstimatorError, match="thrust_port_n"):
        core.on_thrust(bad_thrust)
    with pytest.raises(EstimatorError, match="not finite"):
        core.predict_to(math.nan)  # type: ignore[arg-type]
    with pytest.raises(EstimatorError, match="integer"):
        core.predict_to(1.5)  # type: ignore[arg-type]
    assert core.counters["refused_non_finite"] == 3
    assert core.filter is not None and core.filter.t_ns == 100 * MS  # nothing advanced
    again = core.predict_to(100 * MS)
    assert again == before


def test_a_diverged_filter_is_never_published_and_recovers() -> None:
    core = started()
    core.filter.z[0] = math.nan  # what a numerical failure would leave behind
    assert core.predict_to(50 * MS) is None
    assert core.counters["divergence_resets"] == 1 and not core.initialised
    core.on_gnss(fix(200 * MS, 0.1, 0.0))
    core.on_attitude(att(200 * MS, 0.0))
    est = core.predict_to(250 * MS)
    assert est is not None and all(math.isfinite(v) for v in est.covariance)


@pytest.mark.parametrize(("index", "value"), [(0, 1e27), (1, -4e3), (2, 50.0), (IPSI, math.inf)])
def test_a_state_no_vessel_could_be_in_is_dropped_not_published(index: int, value: float) -> None:
    """On an identified model far from the firmware's boat the filter ran away: it published
    finite speeds of 10^27 m/s, and a heading of inf stopped the estimator with a math domain error
    in the prediction. Past the vessel's envelope the state is dropped, as a non-finite one is,
    without an exception, and the next measurements start it again."""
    core = started()
    core.filter.z[index] = value
    assert core.predict_to(50 * MS) is None
    assert core.counters["divergence_resets"] == 1 and not core.initialised
    notice = core.take_notices()[-1]
    assert notice.kind == "divergence_reset"
    assert ("envelope" in notice.detail) == math.isfinite(value)
    core.on_gnss(fix(200 * MS, 0.1, 0.0))
    core.on_attitude(att(200 * MS, 0.0))
    est = core.predict_to(250 * MS)
    assert est is not None and abs(est.u_mps) < 1.0


def test_heading_innovation_is_wrapped_across_pi() -> None:
    core = started(psi=math.pi - 0.01)
    for k in range(1, 41):
        core.on_attitude(att(k * 50 * MS, -math.pi + 0.01))  # 0.02 rad away, across the cut
    est = core.predict_to(2 * S)
    assert core.counters["heading_rejected"] == 0
    assert abs(abs(est.psi_rad) - math.pi) < 0.012  # near +-pi, never pulled through 0


def test_jacobian_matches_finite_differences_of_the_shared_model() -> None:
    for frame in ("world", "body"):
        core = EstimatorCore(EstimatorConfig(disturbance_frame=frame))
        z = np.array([0.4, -0.05, 0.03, 2.0, -1.0, 0.7, 0.08, -0.1, 0.002])
        thrust = (4.0, 3.0)
        A = core.jacobian(z, thrust)

        def f(zz: np.ndarray, frame: str = frame, thrust: tuple = thrust,
              core: EstimatorCore = core) -> np.ndarray:
            zl = zz.tolist()
            if frame == "world":
                d = model.derivative(zl, thrust, core.p, math, (0, 0, zl[8]), (zl[6], zl[7]))
            else:
                d = model.derivative(zl, thrust, core.p, math, (zl[6], zl[7], zl[8]))
            return np.array([*d, 0.0, 0.0, 0.0])

        h = 1e-6
        fd = np.column_stack([(f(z + h * e) - f(z - h * e)) / (2 * h) for e in np.eye(NZ)])
        np.testing.assert_allclose(A, fd, atol=1e-7)
        assert A[0, 6] != 0.0 and np.all(A[6:, :] == 0.0)


def test_prediction_step_is_rk4_of_the_shared_model_and_f_p_ft_of_its_jacobian() -> None:
    """The compiled step against the float model: the mean is one RK4 step of the six vessel
    states (the disturbance held), the covariance F P F^T + diag(q) h with F = I + Ah + (Ah)^2/2."""
    rng = np.random.default_rng(3)
    for frame in ("world", "body"):
        core = EstimatorCore(EstimatorConfig(disturbance_frame=frame))
        assert core._predictor.compiled
        z = np.array([0.8, -0.05, 0.03, 2.0, -1.0, 2.9, 0.08, -0.1, 0.002])
        L = rng.normal(size=(NZ, NZ)) * 0.05
        P = L @ L.T + np.eye(NZ) * 1e-3
        thrust, h = (4.0, 3.0), 0.05
        z_next, P_next = core._predictor.step(z, P, thrust, h)
        zl = z.tolist()
        if frame == "world":
            x6 = model.rk4_step(zl, thrust, h, core.p, math, (0, 0, zl[8]), (zl[6], zl[7]))
        else:
            x6 = model.rk4_step(zl, thrust, h, core.p, math, (zl[6], zl[7], zl[8]))
        np.testing.assert_allclose(z_next, [*x6, *zl[6:]], rtol=1e-13, atol=1e-14)
        Ah = core.jacobian(z, thrust) * h
        F = np.eye(NZ) + Ah + 0.5 * Ah @ Ah
        ref = F @ P @ F.T + np.diag(core._q * h)
        np.testing.assert_allclose(P_next, 0.5 * (ref + ref.T), rtol=1e-12, atol=1e-15)
        assert np.array_equal(P_next, P_next.T)
        assert z_next is not core._predictor.step(z, P, thrust, h)[0]  # fresh arrays each call


def test_update_is_the_joseph_form_with_its_normalised_innovation() -> None:
    """The compiled update against the textbook: S = HPH' + R, K = PH'S^-1, Joseph form."""
    from seaway_estimator.kalman import Updater

    rng = np.random.default_rng(5)
    L = rng.normal(size=(NZ, NZ)) * 0.1
    P = L @ L.T + np.eye(NZ) * 1e-3
    z = rng.normal(size=NZ)
    cases = [(np.array([0.3]), np.eye(NZ)[[IPSI]], np.array([[0.02]])),
             (np.array([0.4, -0.2]), rng.normal(size=(2, NZ)), np.diag([0.09, 0.04]))]
    for nu, H, R in cases:
        nis, z_next, P_next = Updater(len(nu)).step(z, P, nu, H, R)
        S = H @ P @ H.T + R
        K = P @ H.T @ np.linalg.inv(S)
        IKH = np.eye(NZ) - K @ H
        ref = IKH @ P @ IKH.T + K @ R @ K.T
        assert nis == pytest.approx(float(nu @ np.linalg.solve(S, nu)), rel=1e-12)
        np.testing.assert_allclose(z_next, z + K @ nu, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(P_next, 0.5 * (ref + ref.T), rtol=1e-10, atol=1e-14)
        assert np.array_equal(P_next, P_next.T)


def test_without_a_compiler_the_filter_gives_the_same_estimates(tmp_path, monkeypatch) -> None:
    """The fallback (CasADi evaluating the same functions) through the whole filter: matrices in
    and out of every step, both disturbance frames."""
    from seaway.vessel import native

    def run(cfg: EstimatorConfig) -> list[float]:
        core = started(cfg, psi=0.4)
        core.on_thrust(ThrustCommand(stamp_ns=0, thrust_port_n=4.0, thrust_starboard_n=2.0))
        for k in range(1, 21):
            core.on_attitude(att(k * 50 * MS, 0.4 + 0.002 * k, 0.01))
            if k % 4 == 0:
                core.on_gnss(fix(k * 50 * MS, 0.03 * k, 0.01 * k, vn=0.2, ve=0.05))
        est = core.predict_to(1100 * MS)
        return [est.u_mps, est.x_m, est.psi_rad, est.tau_d_surge_n, *est.covariance]

    for frame in ("world", "body"):
        cfg = FIXED.model_copy(update={"disturbance_frame": frame})
        compiled = run(cfg)
        with monkeypatch.context() as m:
            m.setattr(native.shutil, "which", lambda name: None)
            m.setenv(native.ENV_CACHE_DIR, str(tmp_path / frame))  # nothing compiled there
            assert not EstimatorCore(cfg)._predictor.compiled
            fallback = run(cfg)
        np.testing.assert_allclose(fallback, compiled, rtol=1e-9, atol=1e-12)


def test_a_gated_out_measurement_leaves_the_filter_as_it_was() -> None:
    core = started()
    before_z, before_P = core.filter.z.copy(), core.filter.P.copy()
    assert not core._gated_scalar(50.0, IPSI, 1e-4, 9.0)  # 50 rad off: nis far above the gate
    assert not core._gated_scalar(float("nan"), IPSI, 1e-4, 9.0)
    assert np.array_equal(core.filter.z, before_z) and np.array_equal(core.filter.P, before_P)
    assert core._gated_scalar(0.001, IPSI, 1e-4, 9.0)
    assert core.filter.P[IPSI, IPSI] < before_P[IPSI, IPSI]


def test_commanded_thrust_is_held_then_assumed_stopped_after_the_timeout() -> None:
    def surge_after(timeout_s: float) -> float:
        core = started(EstimatorConfig(origin=FIXED.origin, thrust_timeout_s=timeout_s))
        core.on_thrust(ThrustCommand(stamp_ns=0, thrust_port_n=5.0, thrust_starboard_n=5.0))
        return core.predict_to(5 * S).u_mps

    p = model.load_vessel("paper-sim")
    assert surge_after(10.0) == pytest.approx(10.0 / p.xu_kgps, rel=1e-3)  # steady state
    # One second of thrust, then four of coasting: e^(-4 Xu/m11) of the speed reached.
    x = [0.0] * 6
    for _ in range(100):
        x = model.rk4_step(x, (5.0, 5.0), 0.01, p)
    for _ in range(400):
        x = model.rk4_step(x, (0.0, 0.0), 0.01, p)
    assert surge_after(1.0) == pytest.approx(x[0], rel=1e-3, abs=1e-9)


def test_thrust_is_saturated_to_the_vessel_bounds() -> None:
    core = started()
    core.on_thrust(ThrustCommand(stamp_ns=0, thrust_port_n=50.0, thrust_starboard_n=50.0))
    p = model.load_vessel("paper-sim")
    assert core.predict_to(800 * MS).u_mps < 2 * p.thrust_max_n / p.xu_kgps + 1e-9


def test_late_measurements_are_corrected_within_tolerance_and_refused_beyond() -> None:
    core = started()
    core.predict_to(1 * S)
    core.on_gnss(fix(800 * MS, 0.0, 0.0))
    assert core.counters["late_applied"] == 1 and core.counters["gnss_accepted"] == 1
    core.on_gnss(fix(200 * MS, 0.0, 0.0))  # 0.8 s late > 0.5 s tolerance
    assert core.counters["too_old"] == 1 and core.counters["gnss_accepted"] == 1
    assert core.filter.t_ns == 1 * S


def test_a_time_gap_too_long_to_integrate_drops_the_state() -> None:
    core = started()
    assert core.predict_to(10 * S) is not None
    assert core.predict_to(100 * S) is None  # > max_gap_s = 30 s
    assert core.counters["time_jumps"] == 1 and not core.initialised
    core.on_gnss(fix(100 * S, 1.0, 2.0))
    core.on_attitude(att(100 * S, 0.3))
    est = core.predict_to(100 * S + 50 * MS)
    assert est is not None and est.x_m == pytest.approx(1.0, abs=0.05)


def test_reset_reinitialises_exactly_like_a_fresh_core() -> None:
    def feed(core: EstimatorCore, t0: int) -> list[bytes]:
        out = []
        core.on_thrust(ThrustCommand(stamp_ns=t0, thrust_port_n=3.0, thrust_starboard_n=2.0))
        for k in range(40):
            t = t0 + k * 50 * MS
            core.on_attitude(att(t, 0.2 + 0.001 * k, 0.01))
            if k % 4 == 0:
                core.on_gnss(fix(t, 5.0 + 0.01 * k, 1.0, vn=0.1, ve=0.02))
            est = core.predict_to(t)
            out.append(b"null" if est is None else est.encode())
        return out

    used = EstimatorCore(FIXED)
    feed(used, 0)
    used.on_gnss(fix(3 * S, 40.0, 40.0))  # something to forget
    used.reset()
    assert not used.initialised and used.predict_to(3 * S) is None
    assert used.counters["resets"] == 1
    assert feed(used, 10 * S) == feed(EstimatorCore(FIXED), 10 * S)


def test_reset_can_forget_the_origin_unless_one_is_configured() -> None:
    core = started(EstimatorConfig())
    first = core.origin
    core.reset(keep_origin=False)
    assert core.origin is None
    core.on_gnss(fix(1 * S, 10.0, 0.0))
    assert core.origin is not None and core.origin != first
    fixed = started(FIXED)
    fixed.reset(keep_origin=False)
    assert fixed.origin == GeoOrigin(math.radians(47.0), math.radians(8.0), 0.0)


def test_covariance_stays_symmetric_positive_definite_through_updates_and_gaps() -> None:
    core = started()
    core.on_thrust(ThrustCommand(stamp_ns=0, thrust_port_n=4.0, thrust_starboard_n=3.0))
    for k in range(1, 400):
        t = k * 50 * MS
        if not 100 <= k < 200:  # a 5 s gap in everything
            core.on_attitude(att(t, 0.01 * k, 0.1))
            if k % 4 == 0:
                core.on_gnss(fix(t, 0.02 * k, 0.0))
        P = np.array(core.predict_to(t).covariance).reshape(NZ, NZ)
        assert np.array_equal(P, P.T)
        assert np.linalg.eigvalsh(P).min() > 0


def test_gnss_timeout_sets_degraded_and_position_uncertainty_grows() -> None:
    core = started()
    stds = []
    for k in range(1, 81):  # attitude keeps coming, GNSS does not
        t = k * 50 * MS
        core.on_attitude(att(t, 0.0))
        est = core.predict_to(t)
        stds.append(math.sqrt(est.covariance[IX * NZ + IX] + est.covariance[IY * NZ + IY]))
        assert est.degraded == (t > 2 * S)
    assert all(b > a for a, b in itertools.pairwise(stds))
    assert core.degraded_reasons(4 * S) == ["no GNSS position accepted for 4.0 s"]
    core.on_gnss(fix(4 * S + 50 * MS, 0.0, 0.0))
    assert not core.predict_to(4 * S + 50 * MS).degraded
    assert core.counters["degraded_entered"] == 1


def test_heading_timeout_also_sets_degraded() -> None:
    core = started()
    for k in range(1, 31):
        t = k * 50 * MS
        if k % 4 == 0:
            core.on_gnss(fix(t, 0.0, 0.0))
        assert core.predict_to(t).degraded == (t > 1 * S)


def test_persistent_gnss_offset_is_taken_after_the_configured_run_of_rejections() -> None:
    core = started()
    n = core.config.gnss_reject_reinit_count
    for k in range(1, n + 1):
        t = k * 200 * MS
        core.on_attitude(att(t, 0.0))
        core.on_gnss(fix(t, 50.0, 0.0, vn=None, ve=None))  # the vessel really is 50 m away
    assert core.counters["gnss_rejected"] == n and core.counters["gnss_reinit"] == 1
    assert core.predict_to(n * 200 * MS).x_m == pytest.approx(50.0, abs=0.5)
    core.on_gnss(fix((n + 1) * 200 * MS, 50.1, 0.0))
    assert core.counters["gnss_accepted"] == 1  # this one (the first fix initialised the filter)


def test_config_rejects_unknown_fields() -> None:
    with pytest.raises(ConfigError, match="unknown field"):
        parse_config({"gate_gnss": 10.0, "gate_gnsss": 3.0}, EstimatorConfig)
    assert parse_config({"gate_gnss": 10.0}, EstimatorConfig).gate_gnss == 10.0


NOISE_FIELDS = [n for n, f in EstimatorConfig.model_fields.items() if "std" in n and f.annotation is float]


def _upper_bound(field: str) -> float:
    return next(m.le for m in EstimatorConfig.model_fields[field].metadata if hasattr(m, "le"))


@pytest.mark.parametrize("field", NOISE_FIELDS)
def test_every_noise_setting_has_an_upper_bound_named_when_passed(field: str) -> None:
    """1e200 overflowed building the core (sog_std_mps); 1e200-1e300 in the others gave no estimate
    ever, silently. Past its bound each is refused naming the field and the bound."""
    bound = _upper_bound(field)
    with pytest.raises(ConfigError, match=rf"probe.toml.*\n  {field}: .*less than or equal to {bound:g}"):
        parse_config({field: 1e200}, EstimatorConfig, "probe.toml")


def test_at_the_noise_bounds_the_filter_still_estimates() -> None:
    at_bounds = {f: _upper_bound(f) for f in NOISE_FIELDS}
    core = EstimatorCore(FIXED.model_copy(update=at_bounds))
    for k in range(100):
        t = k * 100 * MS
        core.on_gnss(fix(t, 0.1 * k, 0.0, vn=1.0, ve=0.0))
        core.on_attitude(att(t + MS, 0.0))
        est = core.predict_to(t + 2 * MS)
    assert est is not None and est.x_m == pytest.approx(9.9, abs=1.0) and not est.degraded


def test_state_indices_match_the_message_layout() -> None:
    assert (IX, IY, IPSI) == (3, 4, 5)


def test_the_prediction_takes_the_thrust_the_output_stage_sends_not_the_raw_demand() -> None:
    """On a boat with a 10 N dead zone, vehicle I/O (and the lockstep sim in its place) sends a 6 N
    demand as 10 N and a 4 N one as 0: the filter must predict what the thrusters then produce."""
    boat = EstimatorConfig(origin=FIXED.origin, vessel="paper-boat", apply_dead_zone=True)

    def surge_after(demand_n: float) -> float:
        core = started(boat)
        core.on_thrust(ThrustCommand(stamp_ns=0, thrust_port_n=demand_n, thrust_starboard_n=demand_n))
        return core.predict_to(2 * S).u_mps

    assert surge_after(6.0) == surge_after(10.0) > 0.02  # sent at the dead zone's edge
    assert surge_after(4.0) == surge_after(0.0) == 0.0  # sent as nothing
    assert surge_after(12.0) > surge_after(10.0)  # outside the dead zone: the demand itself


def test_a_clock_stepped_back_drops_the_state_and_the_next_measurements_restart_it() -> None:
    """The times asked for go back an hour (NTP or GPS time stepping the wall clock): nothing can be
    predicted back there, so the state is dropped at once, and measurements stamped on the stepped
    clock re-initialise it. Before, every request was 'too old' and every measurement too: no
    estimate until the clock came back to where the filter was, an hour later."""
    core = EstimatorCore(FIXED)
    core.on_gnss(fix(3600 * S, 0.0, 0.0))
    core.on_attitude(att(3600 * S, 0.0))
    assert core.predict_to(3610 * S) is not None
    back = 10 * S
    assert core.predict_to(back) is None
    assert core.counters["time_jumps"] == 1 and not core.initialised
    core.on_gnss(fix(back + 100 * MS, 1.0, 2.0))
    core.on_attitude(att(back + 100 * MS, 0.3))
    est = core.predict_to(back + 150 * MS)
    assert est is not None and est.x_m == pytest.approx(1.0, abs=0.05)


def test_a_request_back_within_what_a_stamp_may_lie_ahead_keeps_the_state() -> None:
    """A fix may be stamped up to MAX_AHEAD_LIVE_S ahead of the receiver's clock, and moves the filter
    there: a request that far back is too old (None, counted), not a stepped clock."""
    core = started()
    core.predict_to(10 * S)
    core.on_gnss(fix(11 * S, 0.0, 0.0))  # the filter moves to 11 s
    assert core.predict_to(10 * S) is None and core.counters["too_old"] >= 1
    assert core.initialised and core.counters["time_jumps"] == 0
