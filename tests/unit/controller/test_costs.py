"""Cost terms against hand-computed values (reproduction.md items 1-8) and the NLP built from them.

The expected values are computed here from the formulas, with plain floats and no code from the
controller, for a known terminal state and decision.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from seaway.vessel.model import load_vessel, rk4_step
from seaway_controller import costs
from seaway_controller.ocp import SCALE_LENGTH_M, TERMINAL_PENALTY, TIME_SCALE_S, Ocp, OcpSpec

VP = load_vessel("paper-sim")
ALPHA, XU, M33, NR, ARM = VP.alpha_w_per_n2, VP.xu_kgps, VP.m33_kgm2, VP.nr_kgm2ps, VP.arm_m
N = 2.0
TW = 0.49
PREV, ACT = (0.0, 0.0), (8.0, 0.0)
X_H = [0.05, 0.004, 0.01, 3.0, 0.6, 0.1]  # u, v, r, x, y, psi at the end of the horizon
T_D, T_S = 12.0, 80.0


def hand_terms(x_h, t_d, t_s, prev, act, gate=1.0):
    """The paper's terminal terms as reproduction.md reads them, from scratch."""
    u, v, r, x, y, psi = x_h
    raw = math.atan2(act[1] - y, act[0] - x) - math.atan2(v, u) - psi  # item 5
    dpsi = math.atan2(math.sin(raw), math.cos(raw))
    r_max = 2 * dpsi / t_d - r / N  # item 4
    a1 = N * (r_max - r) / t_d
    a2 = -N * r_max / ((N - 1) * t_d)

    def power(rr, rd):  # item 3: N = m33 rdot + Nr r, T = (Xu u +- N/l)/2, P = alpha T^2
        yaw = M33 * rd + NR * rr
        t1, t2 = (XU * u + yaw / ARM) / 2, (XU * u - yaw / ARM) / 2
        return ALPHA * t1 ** 2 + ALPHA * t2 ** 2

    p_d = (TW + (power(r, a1) + power(r_max, a1)) / (2 * N)
           + (N - 1) * (power(r_max, a2) + power(0.0, a2)) / (2 * N))
    p_sur = 2 * ALPHA * (XU * u / 2) ** 2  # item 7
    lx, ly = act[0] - prev[0], act[1] - prev[1]
    e = abs(lx * (y - prev[1]) - ly * (x - prev[0])) / math.hypot(lx, ly)  # item 1
    d = math.hypot(act[0] - x, act[1] - y)
    return {
        "dpsi": dpsi, "e": e, "E_d": p_d * t_d, "E_s": (p_sur + TW) * t_s,
        "Y": gate * e / u * p_sur, "constraint": u * (t_d * math.sin(dpsi) / dpsi + t_s) - d,
        "p_sur": p_sur, "p_d": p_d,
    }


def test_terminal_terms_match_hand_values():
    got = costs.terminal_terms(X_H, T_D, T_S, PREV, ACT, TW, 1.0, N, VP)
    want = hand_terms(X_H, T_D, T_S, PREV, ACT)
    assert got.delta_psi_rad == pytest.approx(want["dpsi"], rel=1e-9)
    assert abs(got.cross_track_m) == pytest.approx(want["e"], rel=1e-12)
    assert got.dynamic_j == pytest.approx(want["E_d"], rel=1e-9)
    assert got.static_j == pytest.approx(want["E_s"], rel=1e-12)
    # |e| is smoothed as sqrt(e^2 + 1e-6): relative error ~ 1e-6 / (2 e^2) at e = 0.6 m.
    assert got.track_j == pytest.approx(want["Y"], rel=5e-6)
    # The distance is smoothed as sqrt(d^2 + 1e-6): off by ~1e-6 / (2 d) = 1e-7 m here.
    assert got.constraint_m == pytest.approx(want["constraint"], abs=5e-7)
    assert got.p_surge_w == pytest.approx(want["p_sur"], rel=1e-12)


def test_track_cost_gated_off_and_positive_when_on():
    off = costs.terminal_terms(X_H, T_D, T_S, PREV, ACT, TW, 0.0, N, VP)
    on = costs.terminal_terms(X_H, T_D, T_S, PREV, ACT, TW, 1.0, N, VP)
    assert off.track_j == 0.0
    assert on.track_j > 0.0
    assert off.dynamic_j == on.dynamic_j and off.static_j == on.static_j


def test_dynamic_power_weights_sum_to_one():
    # Item 3: with no turn left (psi_d = 0, r_H = 0) the profile is flat and P_d must equal P_s.
    u = 0.07
    p_d = costs.dynamic_power_w(u, 0.0, 0.0, 10.0, TW, N, VP)
    assert p_d == pytest.approx(2 * ALPHA * (XU * u / 2) ** 2 + TW, rel=1e-12)
    for n in (2.0, 3.0, 5.0):
        assert costs.dynamic_power_w(u, 0.0, 0.0, 10.0, TW, n, VP) == pytest.approx(p_d, rel=1e-12)


def test_yaw_profile_integrates_to_the_heading_change():
    # Item 4: r_max = 2 psi_d / t_d - r_H / n makes the area under the trapezoid equal psi_d.
    r_h, psi_d, t_d = 0.02, 0.8, 9.0
    r_max, a1, a2 = costs.yaw_profile(r_h, psi_d, t_d, N)
    area = (r_h + r_max) / 2 * (t_d / N) + r_max / 2 * (t_d - t_d / N)
    assert area == pytest.approx(psi_d, rel=1e-12)
    assert r_h + a1 * t_d / N == pytest.approx(r_max, rel=1e-12)
    assert r_max + a2 * (t_d - t_d / N) == pytest.approx(0.0, abs=1e-12)


def test_delta_psi_wraps_across_pi():
    # Item 5: heading 3.1 rad, waypoint almost due south-west behind the -pi cut.
    x_h = [0.05, 0.0, 0.0, 0.0, 0.0, 3.1]
    got = costs.terminal_terms(x_h, T_D, T_S, (1.0, 0.0), (-10.0, -0.1), TW, 1.0, N, VP)
    want = math.atan2(-0.1, -10.0) - 3.1 + 2 * math.pi
    assert got.delta_psi_rad == pytest.approx(want, rel=1e-9)
    assert abs(got.delta_psi_rad) < 0.1


def test_smooth_sinc_is_finite_and_one_at_zero():
    assert costs.smooth_sinc(0.0) == pytest.approx(1.0, abs=1e-8)
    assert costs.smooth_sinc(0.7) == pytest.approx(math.sin(0.7) / 0.7, rel=1e-8)


def test_stage_cost():
    # Item 8: L_k = (alpha (T1^2 + T2^2) + T^w) dt.
    assert costs.stage_cost_j(3.0, -1.5, TW, 0.1, VP) == pytest.approx(
        (ALPHA * (9.0 + 2.25) + TW) * 0.1, rel=1e-12)


def _known_decision(ocp: Ocp, thrusts: list[tuple[float, float]]) -> tuple[np.ndarray, np.ndarray]:
    """w rolled out from rest with ``thrusts``, t_d and t_s set; the gaps are then exactly zero."""
    x0 = [0.02, 0.0, 0.0, 1.0, 0.3, 0.05]
    p = ocp.parameters(np.array(x0), PREV, ACT, True, TW)
    w = np.zeros(ocp.nw)
    x = x0
    for k, t in enumerate(thrusts):
        w[ocp.u_index(k)] = t
        x = rk4_step(x, t, ocp.spec.dt_s, VP)
        w[ocp.x_index(k + 1)] = x
    if ocp.spec.is_empc:
        w[ocp.i_time] = T_D / TIME_SCALE_S
        w[ocp.i_time + 1] = T_S / TIME_SCALE_S
    return w, p


@pytest.mark.parametrize("kind", ["cc-empc", "eo-empc"])
def test_nlp_objective_is_the_sum_of_the_terms(kind):
    ocp = Ocp(OcpSpec(kind), VP)
    thrusts = [(0.8 + 0.05 * k, 0.7 - 0.03 * k) for k in range(ocp.spec.horizon)]
    w, p = _known_decision(ocp, thrusts)
    x_h = list(w[ocp.x_index(ocp.spec.horizon)])
    hand = hand_terms(x_h, T_D, T_S, PREV, ACT, gate=1.0 if kind == "cc-empc" else 0.0)
    stage = sum((ALPHA * (a * a + b * b) + TW) * 0.1 for a, b in thrusts)
    # Scaled by E* = P* L* / u*, the energy to sail L* at the economic cruise u* (P* = 2 T^w there),
    # plus the penalty on the terminal residual c, (rho / 2) (c / L*)^2.
    u_star = math.sqrt(2 * TW / ALPHA) / XU
    e_star = 2 * TW * SCALE_LENGTH_M / u_star
    assert e_star == pytest.approx(98.8, abs=0.1)  # the former fixed scale 0.01 on this vessel
    c = hand["constraint"] / SCALE_LENGTH_M
    want = (stage + hand["E_d"] + hand["E_s"] + hand["Y"]) / e_star + 0.5 * TERMINAL_PENALTY * c * c
    assert float(ocp.objective_fn(w, p)) == pytest.approx(want, rel=1e-6)
    g = np.asarray(ocp.constraint_fn(w, p)).ravel()
    assert np.max(np.abs(g[:-1])) < 1e-12  # every gap closed (X_0 = x_init)
    assert g[-1] == pytest.approx(hand["constraint"], abs=1e-7)


def test_cc_empc_without_gate_equals_eo_empc():
    cc, eo = Ocp(OcpSpec("cc-empc"), VP), Ocp(OcpSpec("eo-empc"), VP)
    w, p = _known_decision(cc, [(1.0, 1.0)] * 10)
    p_off = p.copy()
    p_off[10] = 0.0
    assert float(cc.objective_fn(w, p_off)) == pytest.approx(float(eo.objective_fn(w, p)), rel=1e-12)
    assert float(cc.objective_fn(w, p)) > float(eo.objective_fn(w, p))


def test_nmpc_objective_by_hand():
    weights = costs.NmpcWeights(1.0, 5.0, 2e-3)
    ocp = Ocp(OcpSpec("nmpc", nmpc=weights), VP)
    thrusts = [(6.0, 5.0 + 0.1 * k) for k in range(ocp.spec.horizon)]
    w, p = _known_decision(ocp, thrusts)
    want = 0.0
    for k, (a, b) in enumerate(thrusts):
        _, _, _, x, y, psi = w[ocp.x_index(k + 1)]
        dx, dy = ACT[0] - x, ACT[1] - y
        want += dx * dx + dy * dy + 5.0 * (1 - math.cos(math.atan2(dy, dx) - psi)) + 2e-3 * (a * a + b * b)
    assert float(ocp.objective_fn(w, p)) == pytest.approx(want, rel=1e-12)
    assert ocp.times_s(w) is None


def test_bounds_follow_the_paper():
    ocp = Ocp(OcpSpec("cc-empc"), VP)
    assert ocp.lbw[ocp.u_index(0)].tolist() == [-10.0, -10.0]
    assert ocp.ubw[ocp.u_index(3)].tolist() == [10.0, 10.0]
    with pytest.raises(IndexError):  # X_0 is the measured state (a parameter; may be at rest)
        ocp.x_index(0)
    assert all(ocp.lbw[ocp.x_index(k).start] == 1e-3 for k in range(1, 11))
    assert ocp.lbw[ocp.i_time] * TIME_SCALE_S == pytest.approx(1.0)
    assert ocp.ubw[ocp.i_time] * TIME_SCALE_S == pytest.approx(60.0)
    assert ocp.lbw[ocp.i_time + 1] == 0.0 and ocp.ubw[ocp.i_time + 1] == np.inf


def test_prediction_uses_the_disturbance_parameter():
    ocp = Ocp(OcpSpec("eo-empc"), VP)
    tau = (0.015, 0.02, 0.001)
    x0 = [0.05, 0.0, 0.0, 1.0, 0.3, 0.05]
    p = ocp.parameters(np.array(x0), PREV, ACT, True, TW, tau)
    w = ocp.cold_guess(p)  # rolled out with tau
    g = np.asarray(ocp.constraint_fn(w, p)).ravel()
    assert np.max(np.abs(g[:-1])) < 1e-12
    p0 = ocp.parameters(np.array(x0), PREV, ACT, True, TW)
    assert np.max(np.abs(np.asarray(ocp.constraint_fn(w, p0)).ravel()[:-1])) > 1e-6


@pytest.mark.parametrize("kind", ["cc-empc", "eo-empc", "nmpc"])
def test_prediction_and_price_use_the_thrust_the_thrusters_give(kind):
    """``given`` (a thruster found short): the motion follows ``given * U`` and the energy is priced
    on it, as the simulator's energy metric counts the thrust produced (``seaway.simkit.faults``)."""
    ocp = Ocp(OcpSpec(kind), VP)
    x0 = np.array([0.05, 0.0, 0.0, 1.0, 0.3, 0.05])
    given = (0.5, 1.0)
    p = ocp.parameters(x0, PREV, ACT, True, TW, given=given)
    w = ocp.cold_guess(p)  # rolled out with the thrust given
    gaps = slice(0, ocp.spec.horizon * len(x0))  # the dynamics, not the EMPCs' terminal constraint
    assert np.max(np.abs(np.asarray(ocp.constraint_fn(w, p)).ravel()[gaps])) < 1e-12
    full = ocp.parameters(x0, PREV, ACT, True, TW)
    assert np.max(np.abs(np.asarray(ocp.constraint_fn(w, full)).ravel()[gaps])) > 1e-6
    produced = w.copy()
    for k in range(ocp.spec.horizon):
        produced[ocp.u_index(k)] *= given
    assert float(ocp.objective_fn(w, p)) == pytest.approx(float(ocp.objective_fn(produced, full)),
                                                          rel=1e-12)
    # The warm start's shift holds the last thrust and propagates what the thrusters give of it.
    shifted, _, _ = ocp.shift(w, np.zeros(ocp.nw), np.zeros(ocp.ng), np.zeros(3), given)
    h = ocp.spec.horizon
    want = rk4_step(list(w[ocp.x_index(h)]), [a * b for a, b in zip(w[ocp.u_index(h - 1)], given,
                                                                     strict=True)],
                    ocp.spec.dt_s, VP, math)
    np.testing.assert_allclose(shifted[ocp.x_index(h)], want, rtol=1e-12)
