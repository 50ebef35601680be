"""The vessel model's optional surge friction (seaway.vessel.model): what it does to the motion,
that the simulator's floats and the MPC's CasADi expressions are one law, that a file whose
friction RK4 cannot integrate at the control period is refused, and the steady figures built on it
(the economic cruise, the speed a surge force slides at)."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from pydantic import ValidationError
from seaway.vessel import model
from seaway.vessel.model import VesselParams, load_vessel
from seaway.vessel.model_casadi import continuous_dynamics
from seaway_controller import costs

BASE = load_vessel("px4-sitl-base")


def rover(**kw: float) -> VesselParams:
    """SIH's rover as its source gives it: 20 kg, X_u 60, rolling friction 59 N, 98 N at rest."""
    fields = dict(m11_kg=20.0, xu_kgps=60.0, friction_n=59.0, static_friction_n=98.0,
                  friction_speed_mps=0.5)
    return VesselParams.model_validate({**BASE.model_dump(), **fields, **kw})


def settle(p: VesselParams, surge_n: float, seconds: float = 30.0, dt_s: float = 0.1) -> list[float]:
    x = [0.0] * 6
    for _ in range(round(seconds / dt_s)):
        x = model.rk4_step(x, (surge_n / 2, surge_n / 2), dt_s, p)
    return x


def test_a_vessel_file_without_friction_has_none() -> None:
    for name in ("paper-sim", "paper-boat", "ardupilot-sitl-motorboat"):
        p = load_vessel(name)
        assert not p.has_friction and model.surge_friction_n(1.3, p) == 0.0
        assert model.surge_resistance_n(1.3, p) == p.xu_kgps * 1.3


def test_above_the_sliding_friction_the_speed_is_what_is_left_over_xu() -> None:
    p = rover()
    for surge_n in (160.0, 200.0, 300.0):
        u = settle(p, surge_n)[0]
        assert u == pytest.approx((surge_n - p.friction_n) / p.xu_kgps, rel=0.02), surge_n
        assert u == pytest.approx(model.steady_surge_speed_mps(surge_n, p), rel=0.02)
        assert model.surge_resistance_n(u, p) == pytest.approx(surge_n, rel=0.02)


def test_below_the_breakaway_force_the_vessel_barely_creeps() -> None:
    p, hull = rover(), rover(friction_n=0.0, static_friction_n=0.0)
    for surge_n in (30.0, 50.0):
        held, free = settle(p, surge_n)[0], settle(hull, surge_n)[0]
        assert 0.0 < held < 0.3 * p.friction_speed_mps and free == pytest.approx(surge_n / 60.0)
        assert held < 0.2 * free
    assert model.steady_surge_speed_mps(50.0, p) == 0.0
    assert model.steady_surge_speed_mps(-200.0, p) == pytest.approx(-(200.0 - 59.0) / 60.0)
    # it opposes the motion, whichever way
    assert model.surge_friction_n(-1.0, p) == pytest.approx(-model.surge_friction_n(1.0, p))


def test_near_rest_the_friction_rises_to_the_breakaway_force() -> None:
    p = rover()
    peak = max(model.surge_friction_n(u, p) for u in np.linspace(0.0, 2.0, 401))
    assert peak == pytest.approx(p.static_n, rel=0.05)
    assert model.surge_friction_n(2.0, p) == pytest.approx(p.friction_n, rel=0.01)


def test_the_mpcs_casadi_model_is_the_simulators_law() -> None:
    p = rover()
    f = continuous_dynamics(p)
    rng = np.random.default_rng(4)
    for _ in range(20):
        x = [*rng.normal(0, 0.6, 3), 0.0, 0.0, rng.uniform(-3, 3)]
        u = rng.uniform(-200, 200, 2)
        sym = np.asarray(f(x, u, [0, 0, 0], [0, 0], [0, 0])).ravel()
        assert sym == pytest.approx(model.derivative(x, u, p), rel=1e-12, abs=1e-12)
    # and it is smooth where the MPC needs a gradient: at rest, finite and positive
    xs = ca.SX.sym("x", 6)
    slope = ca.Function("s", [xs], [ca.jacobian(model.surge_friction_n(xs[0], p, ca), xs[0])])
    assert 0 < float(slope([0.0] * 6)) < math.inf


def test_friction_rk4_cannot_integrate_at_the_control_period_is_refused_naming_the_least() -> None:
    with pytest.raises(ValidationError) as err:
        rover(friction_speed_mps=0.1)
    text = str(err.value)
    assert "friction_speed_mps 0.1" in text
    least = float(text.split("need >= ")[1].split(" m/s")[0])
    rover(friction_speed_mps=least * 1.01)  # the least it names loads
    with pytest.raises(ValidationError, match="static_friction_n 10 N must be at least friction_n"):
        rover(static_friction_n=10.0)


def test_at_the_least_speed_allowed_rk4_at_the_control_period_stays_stable() -> None:
    """A vessel on its stiffest allowed friction, started from rest under a small force and from
    speed with none: the 0.1 s RK4 step settles, as the 0.01 s one does, with no oscillation."""
    p = rover()
    least = model.FRICTION_TAU_MIN_S * model.friction_rise_n(p.friction_n, p.static_n) / p.m11_kg
    stiff = rover(friction_speed_mps=least)
    for surge_n, u0 in ((20.0, 0.0), (0.0, 0.4)):
        coarse, fine = [u0] + [0.0] * 5, [u0] + [0.0] * 5
        trace = []
        for _ in range(100):
            coarse = model.rk4_step(coarse, (surge_n / 2, surge_n / 2), 0.1, stiff)
            for _ in range(10):
                fine = model.rk4_step(fine, (surge_n / 2, surge_n / 2), 0.01, stiff)
            trace.append(coarse[0])
        assert coarse[0] == pytest.approx(fine[0], abs=1e-3)
        steps = np.diff(trace)
        assert not ((steps[1:] * steps[:-1]) < -1e-12).any()  # monotone: no sign flips


def test_the_economic_cruise_with_friction_is_the_least_energy_per_metre() -> None:
    p, task_w = rover(), 250.0
    speeds = np.linspace(0.2, 5.0, 20001)
    per_metre = (p.alpha_w_per_n2 * (p.xu_kgps * speeds + p.friction_n) ** 2 / 2 + task_w) / speeds
    best = speeds[int(np.argmin(per_metre))]
    assert costs.cruise_speed_mps(task_w, p) == pytest.approx(best, abs=1e-3)
    # friction makes the cruise faster than the same vessel without it (time costs the task power,
    # and the friction's share of the energy per metre falls with speed)
    hull = rover(friction_n=0.0, static_friction_n=0.0)
    assert costs.cruise_speed_mps(task_w, p) > costs.cruise_speed_mps(task_w, hull)
    assert costs.surge_power_w(1.0, p) == pytest.approx(
        2 * p.alpha_w_per_n2 * ((p.xu_kgps + p.friction_n) / 2) ** 2)
