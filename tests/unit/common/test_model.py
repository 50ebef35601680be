"""The vessel model (paper eq. 1-3): analytic responses, RK4 accuracy, one model for all paths."""

from __future__ import annotations

import math

import pytest
from seaway.vessel import model
from seaway.vessel.model import load_vessel

P = load_vessel("paper-sim")


def integrate(x, thrust, t_s, dt_s, **kw):
    for _ in range(round(t_s / dt_s)):
        x = model.rk4_step(x, thrust, dt_s, P, math, **kw)
    return x


def test_surge_decays_with_time_constant_m11_over_xu() -> None:
    tau_s = P.m11_kg / P.xu_kgps
    x = integrate([1.0, 0, 0, 0, 0, 0], (0.0, 0.0), tau_s, tau_s / 100)
    assert x[0] == pytest.approx(math.exp(-1.0), rel=1e-7)
    # And the distance travelled is the integral u0 * tau * (1 - e^-1).
    assert x[3] == pytest.approx(tau_s * (1 - math.exp(-1.0)), rel=1e-7)


def test_steady_surge_speed_is_total_thrust_over_xu() -> None:
    x = integrate([0.0] * 6, (3.0, 3.0), 15.0, 0.01)
    assert x[0] == pytest.approx(6.0 / P.xu_kgps, rel=1e-9)
    assert x[1] == pytest.approx(0.0, abs=1e-12) and x[2] == pytest.approx(0.0, abs=1e-12)


def test_steady_yaw_rate_is_differential_moment_over_nr() -> None:
    # T1 = -T2: a pure moment, so u = v = 0 and the Coriolis terms vanish.
    x = integrate([0.0] * 6, (0.5, -0.5), 150.0, 0.01)
    assert x[2] == pytest.approx(1.0 * P.arm_m / P.nr_kgm2ps, rel=1e-8)
    assert x[0] == pytest.approx(0.0, abs=1e-12)


def test_positive_differential_thrust_turns_clockwise_to_starboard() -> None:
    x = integrate([0.3, 0, 0, 0, 0, 0], (2.0, 1.0), 2.0, 0.01)
    assert x[2] > 0 and x[5] > 0 and x[4] > 0  # r > 0, heading east of north, moved east


def test_rk4_agrees_with_a_fine_step_reference() -> None:
    kw = dict(tau_body=(0.015, 0.015, 0.001), force_ne=(-0.0987, 0.0868), current_ne=(0.05, -0.02))
    x0 = [0.4, 0.05, 0.1, 1.0, -2.0, 0.3]
    coarse = integrate(list(x0), (4.0, 1.5), 5.0, 0.01, **kw)
    fine = integrate(list(x0), (4.0, 1.5), 5.0, 1e-4, **kw)
    for a, b in zip(coarse, fine, strict=True):
        assert abs(a - b) < 1e-6


def test_world_force_is_rotated_into_the_body_frame() -> None:
    # Heading east (psi = pi/2): a force to the east is pure surge, a force to the north is -sway.
    d = model.derivative([0, 0, 0, 0, 0, math.pi / 2], (0, 0), P, math, force_ne=(0.0, 1.0))
    assert d[0] == pytest.approx(1.0 / P.m11_kg) and d[1] == pytest.approx(0.0, abs=1e-15)
    d = model.derivative([0, 0, 0, 0, 0, math.pi / 2], (0, 0), P, math, force_ne=(1.0, 0.0))
    assert d[1] == pytest.approx(-1.0 / P.m22_kg) and d[0] == pytest.approx(0.0, abs=1e-15)


def test_current_carries_the_vessel() -> None:
    x = integrate([0.0] * 6, (0.0, 0.0), 10.0, 0.01, current_ne=(0.1, -0.2))
    assert x[3] == pytest.approx(1.0) and x[4] == pytest.approx(-2.0)
    assert x[0] == 0.0


def test_power_is_alpha_t_squared_per_thruster() -> None:
    assert model.propulsion_power_w((2.0, -3.0), P) == pytest.approx(0.4364 * 13.0)


def test_wrench_inverse() -> None:
    t = model.thrusts_for_wrench(5.0, 0.2, P)
    assert model.wrench(t, P)[0] == pytest.approx(5.0)
    assert model.wrench(t, P)[2] == pytest.approx(0.2)


def test_casadi_form_is_the_same_model() -> None:
    ca = pytest.importorskip("casadi")
    from seaway.vessel.model_casadi import continuous_dynamics, rk4_discrete

    x = [0.4, 0.05, 0.1, 1.0, -2.0, 0.3]
    f = continuous_dynamics(P)
    num = model.derivative(x, (4.0, 1.5), P, math, (0.01, 0.02, 0.0), (0.1, -0.1), (0.0, 0.05))
    sym = f(x, [4.0, 1.5], [0.01, 0.02, 0.0], [0.1, -0.1], [0.0, 0.05]).full().ravel()
    assert list(sym) == pytest.approx(num, abs=1e-14)
    step = rk4_discrete(P, 0.1, with_disturbance=False)
    assert list(step(x, [4.0, 1.5]).full().ravel()) == pytest.approx(
        model.rk4_step(x, (4.0, 1.5), 0.1, P, math), abs=1e-13)
    assert isinstance(step, ca.Function)


def test_vessel_files_load_and_differ_only_in_thrusters() -> None:
    boat = load_vessel("paper-boat")
    assert (P.thrust_max_n, P.dead_zone_n) == (10.0, 0.0)
    assert (boat.thrust_max_n, boat.dead_zone_n) == (75.0, 10.0)
    assert P.m11_kg == boat.m11_kg == 12.84


def test_rk4_step_is_the_textbook_step_to_the_last_bit() -> None:
    """The plant, the estimator and the controller's budget all step through ``rk4_step``: written
    for speed, it must still be exactly the classical step (same operations, same order: a sum
    regrouped differs in the last bit somewhere among these draws), whatever sequence the state
    comes in, and leave the caller's state as it was."""
    np = pytest.importorskip("numpy")
    rng = np.random.default_rng(7)
    for _ in range(200):
        x = [float(v) for v in rng.normal(0.0, [0.8, 0.2, 0.2, 50.0, 50.0, 2.0])]
        thrust = tuple(float(v) for v in rng.uniform(-10.0, 10.0, 2))
        h = float(rng.uniform(0.001, 0.2))
        kw = {"tau_body": tuple(float(v) for v in rng.normal(0.0, 0.5, 3)),
              "force_ne": tuple(float(v) for v in rng.normal(0.0, 2.0, 2)),
              "current_ne": tuple(float(v) for v in rng.normal(0.0, 0.1, 2))}

        def f(xs, thrust=thrust, kw=kw):
            return model.derivative(xs, thrust, P, math, **kw)

        k1 = f(x)
        k2 = f([x[i] + 0.5 * h * k1[i] for i in range(6)])
        k3 = f([x[i] + 0.5 * h * k2[i] for i in range(6)])
        k4 = f([x[i] + h * k3[i] for i in range(6)])
        textbook = [x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(6)]
        before = list(x)
        for given in (x, tuple(x), np.array(x)):
            assert [float(v) for v in model.rk4_step(given, thrust, h, P, math, **kw)] == textbook
        assert x == before
