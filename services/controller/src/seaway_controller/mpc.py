"""One receding-horizon controller: parameters, warm start, the solve, and its numbers in SI units.

Warm start (solver-notes.md, trap 5): the last good solution, primal and dual, shifted by the number
of periods since it was computed; when the active waypoint changed, t_d and t_s are re-guessed from
the new geometry and their multipliers cleared. Headings in the guess are moved by whole turns to
match the measured heading (the estimate is wrapped to (-pi, pi], the prediction is continuous).

The cross-track gate (reproduction.md item 2) is decided here, once per solve, from the previous
plan's terminal position when there is one and from the measured position otherwise.

``solve`` does not keep its result: the caller ``accept``s it when it is good and on time, so that a
failed or late solve never becomes the plan that is reused or warm-started from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from seaway.vessel.thrusters import FULL_THRUST

from seaway_controller import costs
from seaway_controller.ocp import P_ACTIVE, P_GATE, P_GIVEN, P_PREV, P_TASK, P_TAU, Ocp
from seaway_controller.solvers import NlpSolver, SolveResult

TWO_PI = 2.0 * math.pi


@dataclass
class Plan:
    """A solved prediction, in SI units, with what the warm start needs."""

    result: SolveResult
    states: np.ndarray  # (H+1, 6)
    thrusts_n: np.ndarray  # (H, 2)
    leg_key: tuple
    stamp_ns: int  # stamp of the state it was solved from


@dataclass
class Costs:
    """The cost split of one prediction [J] (EMPC terms are None for the NMPC)."""

    stage_j: float
    dynamic_j: float | None
    static_j: float | None
    track_j: float | None
    t_d_s: float | None
    t_s_s: float | None
    cross_track_m: float | None

    @property
    def energy_to_go_j(self) -> float | None:
        """Predicted energy to reach the active waypoint: horizon + E_d + E_s [J]."""
        if self.dynamic_j is None or self.static_j is None:
            return None
        return self.stage_j + self.dynamic_j + self.static_j


@dataclass
class MpcOutcome:
    result: SolveResult
    plan: Plan
    costs: Costs
    track_gate: bool


class MpcController:
    """Solves one controller's OCP step after step, keeping its own warm start."""

    def __init__(self, ocp: Ocp, solver: NlpSolver) -> None:
        self.ocp, self.solver = ocp, solver
        self.spec, self.vessel = ocp.spec, ocp.vessel
        # Asked every period: looked up once (``OcpSpec.is_empc`` looks the controller up).
        self._empc = self.spec.is_empc
        self._terminal = ocp.controller.terminal
        self.last_good: Plan | None = None
        self.capture: list[tuple[np.ndarray, ...]] | None = None  # bench: record NLP instances

    def reset(self) -> None:
        self.last_good = None

    def plan_age(self, now_ns: int) -> int | None:
        """Periods since the last good plan was solved, or None if there is no usable one."""
        if self.last_good is None:
            return None
        age = round((now_ns - self.last_good.stamp_ns) / (self.spec.dt_s * 1e9))
        return age if 0 <= age < self.spec.horizon else None

    def track_gate(self, now_ns: int, x0: np.ndarray, wp_prev: tuple[float, float],
                   wp_active: tuple[float, float], coa_radius_m: float) -> bool:
        """e counts only when the terminal position is outside both circles (item 2)."""
        if self.plan_age(now_ns) is not None:
            assert self.last_good is not None
            pos = self.last_good.states[-1, 3:5].tolist()  # floats: math.dist reads them faster
        else:
            pos = x0[3:5].tolist()
        r_f = min(math.dist(pos, wp_prev), math.dist(pos, wp_active))
        return r_f > coa_radius_m

    def _warm_start(self, now_ns: int, x0: np.ndarray, p: np.ndarray, leg_key: tuple
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ocp = self.ocp
        plan, age = self.last_good, self.plan_age(now_ns)
        if plan is None or age is None:
            w = ocp.cold_guess(p)
            return (w, *self._cold_duals(w, p))
        r = plan.result
        w, lx, lg = r.w, r.lam_x, r.lam_g
        if r.interior_point:  # IPOPT's multipliers would stall the SQP (SolveResult.interior_point)
            lx, lg = self._cold_duals(w, p)
        tau = p[P_TAU:P_TAU + 3]
        given = (float(p[P_GIVEN]), float(p[P_GIVEN + 1]))
        for _ in range(age):
            w, lx, lg = ocp.shift(w, lx, lg, tau, given)
        if not age:  # shifted, ``w`` is a new array already; unshifted, it is the plan's own
            w = w.copy()
        # Whole turns: align the guess's headings with the measured one (X_1 follows X_0 closely).
        turns = round((w[ocp.x_index(1)][5] - x0[5]) / TWO_PI)
        if turns:
            for k in range(1, self.spec.horizon + 1):
                w[ocp.x_index(k).start + 5] -= turns * TWO_PI
        if self._empc and leg_key != plan.leg_key:
            ocp.guess_times(w, p)
            lx[ocp.i_time:ocp.i_time + 2] = 0.0
            lg[-1] = ocp.terminal_multiplier_guess(w, p)
        return w, lx, lg

    def _cold_duals(self, w: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lam_x, lam_g) of a start without multipliers for the guess ``w``: zero, but the
        EMPC's terminal-time constraint, whose multiplier is guessed from ``w``."""
        lg = np.zeros(self.ocp.ng)
        if self._empc:
            lg[-1] = self.ocp.terminal_multiplier_guess(w, p)
        return np.zeros(self.ocp.nw), lg

    def solve(self, now_ns: int, x0: np.ndarray, wp_prev: tuple[float, float],
              wp_active: tuple[float, float], coa_radius_m: float, task_power_w: float, leg_key: tuple,
              tau_d: tuple[float, float, float] = (0.0, 0.0, 0.0),
              given: tuple[float, float] = FULL_THRUST) -> MpcOutcome:
        """Solve from the measured state ``x0`` for the leg (P_{i-1}, P_i); ``leg_key`` names it.
        ``given``: the fraction of its command each thruster gives (``ocp`` module docstring)."""
        x0 = np.asarray(x0, dtype=float)
        gate = self.track_gate(now_ns, x0, wp_prev, wp_active, coa_radius_m)
        p = self.ocp.parameters(x0, wp_prev, wp_active, gate, task_power_w, tau_d, given)
        w0, lx0, lg0 = self._warm_start(now_ns, x0, p, leg_key)
        if self.capture is not None:
            self.capture.append((w0.copy(), p.copy(), lx0.copy(), lg0.copy()))
        result = self.solver.solve(w0, p, lx0, lg0)
        thrusts = self.ocp.thrusts(result.w)
        plan = Plan(result, self.ocp.states(result.w, x0), thrusts, leg_key, now_ns)
        return MpcOutcome(result, plan, self.evaluate(result.w, p, thrusts), gate)

    def accept(self, outcome: MpcOutcome) -> None:
        """Keep ``outcome`` as the plan to reuse and warm-start from (a good, timely solve)."""
        self.last_good = outcome.plan

    def evaluate(self, w: np.ndarray, p: np.ndarray, thrusts_n: np.ndarray | None = None) -> Costs:
        """The cost split of a prediction, in joules, from the same formulas as the NLP
        (``thrusts_n``: ``Ocp.thrusts(w)`` when the caller has it already)."""
        ocp, spec, vp = self.ocp, self.spec, self.vessel
        task = float(p[P_TASK])
        if thrusts_n is None:
            thrusts_n = ocp.thrusts(w)
        # Python floats, not numpy scalars: the same IEEE operations, at a fraction of the cost.
        stage_cost, dt_s = costs.stage_cost_j, spec.dt_s
        stage = float(sum([stage_cost(t1, t2, task, dt_s, vp) for t1, t2 in thrusts_n.tolist()]))
        times, terminal = ocp.times_s(w), self._terminal
        if times is None or terminal is None:  # no terminal terms (the NMPC)
            return Costs(stage, None, None, None, None, None, None)
        t_d, t_s = times
        x_h = w[ocp.x_index(spec.horizon)].tolist()
        if not x_h[0] > 0:  # an unconverged iterate may violate u_H > 0; no finite Y then
            return Costs(stage, None, None, None, t_d, t_s, None)
        # The controller's own terminal terms, with numbers: the gate counts only where its NLP
        # uses it (CC-EMPC's Y), so the split reported is the one the solver minimised.
        term = terminal(x_h, t_d, t_s, p[P_PREV:P_PREV + 2].tolist(),
                        p[P_ACTIVE:P_ACTIVE + 2].tolist(), task, float(p[P_GATE]), spec, vp, math)
        return Costs(stage, float(term.dynamic_j), float(term.static_j), float(term.track_j), t_d,
                     t_s, float(term.cross_track_m))

