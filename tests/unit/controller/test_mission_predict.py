"""The mission chooses whether the controller predicts with the estimated tau_d; the process flag
makes every mission do so; a resumed mission keeps its choice."""

from __future__ import annotations

from pathlib import Path

import pytest
from seaway.contract.messages import StateEstimate
from seaway.vessel.thrusters import loss_of
from seaway_controller import checkpoint
from seaway_controller.checkpointing import resume

from tests.unit.controller.test_core import VP, CapturingSolver, make_core, mission

TAU_D = [0.015, 0.02, 0.001]


def disturbed_state(stamp_ns: int = 7, x: float = 2.0) -> StateEstimate:
    return StateEstimate.make(stamp_ns=stamp_ns, u_mps=0.05, v_mps=0.0, r_radps=0.0, x_m=x, y_m=0.5,
                              psi_rad=0.3, tau_d_surge_n=TAU_D[0], tau_d_sway_n=TAU_D[1],
                              tau_d_yaw_nm=TAU_D[2])


def predicting(**kw):
    return mission().model_copy(update=kw)


def predicted_tau_d(solver: CapturingSolver, call: int = -1) -> list[float]:
    return solver.params[call][12:15].tolist()  # the OCP's tau_d parameter


@pytest.mark.parametrize(("flag", "asks", "predicts"), [
    (False, False, False), (False, True, True), (True, False, True), (True, True, True)])
def test_the_active_mission_or_the_flag_decides(flag: bool, asks: bool, predicts: bool) -> None:
    solver = CapturingSolver()
    core = make_core(solver, predict_disturbance=flag)
    reply = core.handle_mission(0, predicting(predict_disturbance=asks))
    assert reply.accepted and reply.detail["predict_disturbance"] is predicts
    assert core.predict_disturbance is predicts
    core.step(7, disturbed_state())
    assert predicted_tau_d(solver) == (TAU_D if predicts else [0.0, 0.0, 0.0])


def test_each_mission_makes_its_own_choice() -> None:
    solver = CapturingSolver()
    core = make_core(solver)
    assert not core.predict_disturbance  # no mission: nothing asks
    core.handle_mission(0, predicting(predict_disturbance=True, controller="nmpc"))
    core.step(7, disturbed_state())
    assert predicted_tau_d(solver) == TAU_D
    core.handle_mission(0, predicting(predict_disturbance=False))  # the next mission does not ask
    core.step(100_000_007, disturbed_state(100_000_007))
    assert predicted_tau_d(solver) == [0.0, 0.0, 0.0]
    # A refused mission leaves the current one (and its choice) in place.
    bad = predicting(predict_disturbance=True, coa_radius_m=-1.0)
    assert not core.handle_mission(0, bad).accepted
    core.step(200_000_007, disturbed_state(200_000_007))
    assert predicted_tau_d(solver) == [0.0, 0.0, 0.0]


def test_a_resumed_mission_keeps_predicting(tmp_path: Path) -> None:
    core = make_core(CapturingSolver())
    assert core.handle_mission(0, predicting(predict_disturbance=True)).accepted
    for k in range(3):
        core.step(k * 100_000_000 + 7, disturbed_state(k * 100_000_000 + 7, x=2.0 + k))
    req, leg, st, energy = core.progress()
    path = tmp_path / "cp.json"
    checkpoint.save(path, checkpoint.MissionCheckpoint(request=req.model_dump(mode="json"),
                                                       active_leg=leg, state=st,
                                                       energy_used_j=energy, saved_unix_ns=1))
    assert checkpoint.load(path).mission_request().predict_disturbance is True
    solver = CapturingSolver()
    fresh = make_core(solver)  # a restarted process without the flag
    resume(fresh, path, 10)
    assert fresh.progress()[1:3] == (leg, "active") and fresh.predict_disturbance
    fresh.step(500_000_007, disturbed_state(500_000_007, x=4.0))
    assert predicted_tau_d(solver) == TAU_D


def test_a_thruster_found_short_is_planned_with_and_not_counted_twice() -> None:
    """A ``StateEstimate`` saying a side short: the plan models it (the OCP's ``given``), and the
    disturbance predicted with is the estimate's less the loss at the last command, which the
    estimate's carries as unexplained and the plan now explains."""
    solver = CapturingSolver()
    core = make_core(solver)
    assert core.handle_mission(0, predicting(predict_disturbance=True)).accepted
    short = disturbed_state().model_copy(update={"thrust_short_side": "port",
                                                 "thrust_short_frac": 0.4})
    first = core.step(7, short)[0]
    assert solver.params[-1][15:17].tolist() == pytest.approx([0.6, 1.0])
    assert (first.thrust_port_n, first.thrust_starboard_n) != (0.0, 0.0)
    core.step(100_000_007, short.model_copy(update={"stamp_ns": 100_000_007}))
    surge_n, yaw_nm = loss_of(first.thrust_port_n, first.thrust_starboard_n, (0.6, 1.0),
                              VP.arm_m)
    assert predicted_tau_d(solver) == pytest.approx([TAU_D[0] - surge_n, TAU_D[1],
                                                     TAU_D[2] - yaw_nm])
    assert surge_n < 0.0 and yaw_nm < 0.0
    # Without a loss said: all of the thrust given, the estimate's disturbance as it is.
    core.step(200_000_007, disturbed_state(200_000_007))
    assert solver.params[-1][15:17].tolist() == [1.0, 1.0]
    assert predicted_tau_d(solver) == TAU_D
