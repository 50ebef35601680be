"""The optimal control problems: CC-EMPC (paper eq. 15), EO-EMPC (eq. 15 without Y) and NMPC.

This module is the skeleton every controller shares; what differs (stage cost, terminal terms, cold
guess) comes from the controller registered under ``OcpSpec.kind`` (``seaway_controller.controllers``).

Multiple shooting over H steps of dt with the gaps written ``X_{k+1} - F(X_k, U_k)`` (solver-notes.md,
trap 5), F being the shared RK4 step of the vessel model (``seaway.vessel.model_casadi.rk4_discrete``).
X_0 is the measured state, a parameter (not a variable pinned by an equality), which keeps the QP
that the SQP factorises at every iteration smaller::

    w = [U_0, X_1, U_1, X_2, ..., U_{H-1}, X_H, (t_d/100, t_s/100 for the EMPCs)]
    p = [x_init(6), P_{i-1}(2), P_i(2), track_gate, T^w, tau_d(3), given(2)]
    g = [X_{k+1} - F(X_k, given * U_k, tau_d) for k < H (X_0 = x_init), (terminal constraint, EMPCs)]

X = [u, v, r, x, y, psi] (body speeds, NED position and heading), U = [T1 port, T2 starboard] [N],
the thrust commanded, which the bounds limit. The motion follows, and the stage energy is priced on,
what the thrusters give of it (``given * U``, ``given`` the fraction of its command each gives: 1, 1
but for a thruster the estimator found short, ``seaway.vessel.thrusters.given_fractions``), as the
simulator's energy metric counts the thrust produced.

Scaling (solver-notes.md, trap 1), from the vessel and the mission's task power so that one NLP shape
serves a 0.045 m/s lab model and a 1 m/s boat alike (``empc_scales``): the EMPCs optimise t/100
instead of t for t_d and t_s, and minimise J / E* + (rho/2) (c / L*)^2, E* = P* L* / u* being the
energy to sail L* = 4.5 m at the economic cruise u* (P* = T^w + P^sur(u*) = 2 T^w; E* = 98.8 J on the
paper's vessel, a scale of about 0.01, and 2232 J on the lake boat) and c the terminal
constraint's residual. The penalty is zero, with a zero gradient, at every feasible point, so the
optimum and its multipliers are those of the paper's problem; it makes the terminal block of the
Hessian (bilinear in u_H and t_s) positive definite, so that eigen-clip leaves it alone instead of
clipping a negative eigenvalue (linear convergence at rate ~0.8, measured on the lake). Every number
reported is unscaled. tau_d is zero unless the controller is told to predict with the estimated
disturbance.
"""

from __future__ import annotations

import hashlib
import inspect
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np
from seaway.contract.messages import ControllerName
from seaway.vessel import model
from seaway.vessel.model import NU, NX, VesselParams
from seaway.vessel.model_casadi import rk4_discrete
from seaway.vessel.thrusters import FULL_THRUST, given_pair

from seaway_controller import controllers, costs

ControllerKind = ControllerName
"""A registered controller's name (``seaway.contract.messages.ControllerName``)."""
CONTROLLER_KINDS: tuple[ControllerKind, ...] = controllers.NAMES

TIME_SCALE_S = 100.0
"""t_d and t_s enter the NLP as t / TIME_SCALE_S (solver-notes.md, trap 1)."""
SCALE_LENGTH_M = 4.5
"""L*: the EMPC objective's energy unit is the energy to sail this far at cruise (module docstring)."""
TERMINAL_PENALTY = 0.3
"""rho: weight of (c / L*)^2 / 2 in the scaled EMPC objective (zero at feasible points). Measured
(lake and paper c1-c5, true state): 0 leaves the lake at a median of 4 SQP iterations (max 50);
0.1-1 all give zero unconverged and a median of 2-3; 1 adds a third iteration to a third of the
paper's solves, 0.3 to an eighth (as the fixed scaling did to 7 %), 0.1 fails more cold starts."""
MIN_SCALE_SPEED_MPS = 0.01
"""u* used for scaling is at least this, so that a zero task power still gives finite scales."""


def empc_scales(task_power_w, vessel: VesselParams, ops=math):
    """(u* [m/s], E* [J]) for the EMPC scaling; numbers with ``math``, expressions with ``casadi``."""
    u_star = getattr(ops, "fmax", max)(costs.cruise_speed_mps(task_power_w, vessel, ops),
                                       MIN_SCALE_SPEED_MPS)
    p_star = task_power_w + costs.surge_power_w(u_star, vessel)
    return u_star, p_star * SCALE_LENGTH_M / u_star


def empc_objective_scale(task_power_w: float, vessel: VesselParams) -> float:
    """1 / E*: the scaled NLP objective is J times this, plus the (zero when feasible) penalty."""
    return 1.0 / empc_scales(task_power_w, vessel)[1]


NP = 17
"""Length of the parameter vector p (module docstring)."""
P_X0, P_PREV, P_ACTIVE, P_GATE, P_TASK, P_TAU, P_GIVEN = 0, 6, 8, 10, 11, 12, 15


@dataclass(frozen=True)
class OcpSpec:
    """Everything that defines one problem; its hash names the generated solver.

    Paper values (section V-A, reproduction.md): H = 10, dt = 0.1 s, n = 2, t_d in [1, 60] s
    (solver-notes.md trap 2: t_d >= 1 s), u_k >= 1e-3 m/s on predicted steps.
    """

    kind: ControllerKind
    horizon: int = 10
    dt_s: float = 0.1
    profile_n: float = 2.0
    t_d_min_s: float = 1.0
    t_d_max_s: float = 60.0
    u_min_mps: float = 1e-3
    nmpc: costs.NmpcWeights = field(default_factory=costs.NmpcWeights)

    def __post_init__(self) -> None:
        controllers.get(self.kind)  # ValueError naming the known controllers
        if self.horizon < 1 or not self.dt_s > 0:
            raise ValueError("horizon must be >= 1 and dt_s > 0")
        if not self.profile_n > 1:
            raise ValueError("profile_n must be > 1 (r_max needs n > 1, reproduction.md item 4)")
        if not 0 < self.t_d_min_s < self.t_d_max_s:
            raise ValueError("need 0 < t_d_min_s < t_d_max_s")

    @property
    def controller(self) -> controllers.Controller:
        """The registered controller this problem is built from."""
        return controllers.get(self.kind)

    @property
    def is_empc(self) -> bool:
        """An economic MPC: t_d, t_s and the terminal constraint are part of the problem."""
        return self.controller.economic


def spec_digest(spec: OcpSpec, vessel: VesselParams, extra: dict | None = None) -> str:
    """A stable hash of the problem (spec, vessel, formulation code) and ``extra`` (solver options).

    The code hashed is every file the NLP is built from: this one, the cost terms, the controller
    definitions (``controllers/*.py``, and the file of a controller loaded from elsewhere,
    ``controllers.load_module``) and the shared vessel maths they call (``seaway.vessel``'s model
    and path geometry), so that editing any of them rebuilds the cached solver."""
    from seaway.vessel import model, model_casadi, path

    here = Path(__file__).parent
    files = [here / "costs.py", here / "ocp.py", *sorted((here / "controllers").glob("*.py")),
             *(Path(m.__file__) for m in (model, model_casadi, path))]
    c = spec.controller
    sources = [controllers.source_file(spec.kind),
               *(inspect.getsourcefile(fn) for fn in (c.stage_cost, c.guess_thrust, c.terminal)
                 if fn is not None)]
    for source in sources:
        if source is not None and Path(source).resolve() not in {f.resolve() for f in files}:
            files.append(Path(source))
    code = "".join(f.read_text() for f in files)
    doc = {"spec": asdict(spec), "vessel": vessel.model_dump(), "extra": extra or {},
           "casadi": ca.__version__, "code": hashlib.sha256(code.encode()).hexdigest()}
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()[:20]


class Ocp:
    """One problem: the NLP, its bounds, and index helpers for guesses and warm starts."""

    def __init__(self, spec: OcpSpec, vessel: VesselParams, scaled: bool = True,
                 graph: str = "SX") -> None:
        """``scaled=False`` builds the paper's problem as written (J in joules, times in seconds, no
        penalty): the same optimum, badly conditioned; the tests solve it with IPOPT as a reference.

        ``graph``: "SX" (default) builds the NLP as one scalar expression graph, which is what the
        generated solver needs and what ``nlpsol``'s ``expand`` option would produce. "MX" builds
        the same expressions as a matrix graph that calls the RK4 step function once per stage, the
        way CasADi's Opti stack and its multiple-shooting examples do: the baseline that
        ``seaway bench controller`` calls plain IPOPT (solver-notes.md counts expanding to SX as a
        tuning step)."""
        if graph not in ("SX", "MX"):
            raise ValueError(f"graph must be 'SX' or 'MX', not {graph!r}")
        self.spec, self.vessel, self.scaled, self.graph = spec, vessel, scaled, graph
        self.controller = spec.controller
        self.time_scale_s = TIME_SCALE_S if scaled else 1.0
        h = spec.horizon
        self.stage = NU + NX  # block k = [U_k, X_{k+1}]
        self.i_time = h * self.stage
        self.nw = self.i_time + (2 if spec.is_empc else 0)
        self.ng = NX * h + (1 if spec.is_empc else 0)
        self.F = rk4_discrete(vessel, spec.dt_s, with_disturbance=True)
        self._build()

    # -- indices -------------------------------------------------------------------------------

    def x_index(self, k: int) -> slice:
        """Where X_k (k = 1..H) sits in w; X_0 is the parameter x_init."""
        if not 1 <= k <= self.spec.horizon:
            raise IndexError(f"X_{k} is not a decision variable (k must be 1..{self.spec.horizon})")
        start = (k - 1) * self.stage + NU
        return slice(start, start + NX)

    def u_index(self, k: int) -> slice:
        start = k * self.stage
        return slice(start, start + NU)

    def states(self, w: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """(H+1, 6) predicted states, X_0 = x0 first."""
        h = self.spec.horizon
        out = np.empty((h + 1, NX))
        out[0] = x0
        out[1:] = w[: h * self.stage].reshape(h, self.stage)[:, NU:]  # the blocks' X_{k+1}
        return out

    def thrusts(self, w: np.ndarray) -> np.ndarray:
        """(H, 2) planned thrusts [N]."""
        h = self.spec.horizon
        return w[: h * self.stage].reshape(h, self.stage)[:, :NU].copy()  # the blocks' U_k

    def times_s(self, w: np.ndarray) -> tuple[float, float] | None:
        """(t_d, t_s) [s], unscaled; None for the NMPC."""
        if not self.spec.is_empc:
            return None
        ts = self.time_scale_s
        return float(w[self.i_time] * ts), float(w[self.i_time + 1] * ts)

    # -- the NLP -------------------------------------------------------------------------------

    def _build(self) -> None:
        s, vp = self.spec, self.vessel
        sym = ca.MX.sym if self.graph == "MX" else ca.SX.sym
        w = sym("w", self.nw)
        p = sym("p", NP)
        x_init = p[P_X0:P_X0 + NX]
        wp_prev, wp_act = p[P_PREV:P_PREV + 2], p[P_ACTIVE:P_ACTIVE + 2]
        gate, task, tau = p[P_GATE], p[P_TASK], p[P_TAU:P_TAU + 3]
        given = p[P_GIVEN:P_GIVEN + NU]
        xs = [x_init] + [w[self.x_index(k)] for k in range(1, s.horizon + 1)]
        us = [w[self.u_index(k)] for k in range(s.horizon)]
        ctl = self.controller
        g = []
        stage = 0
        for k in range(s.horizon):
            produced = us[k] * given
            g.append(xs[k + 1] - self.F(xs[k], produced, tau))
            stage += ctl.stage_cost(xs[k + 1], produced, wp_act, task, s, vp, ca)
        if ctl.terminal is not None:
            t_d = w[self.i_time] * self.time_scale_s
            t_s = w[self.i_time + 1] * self.time_scale_s
            term = ctl.terminal(xs[-1], t_d, t_s, wp_prev, wp_act, task, gate, s, vp, ca)
            energy = stage + term.dynamic_j + term.static_j + term.track_j
            if self.scaled:
                _, e_star = empc_scales(task, vp, ca)
                c_rel = term.constraint_m / SCALE_LENGTH_M
                objective = energy / e_star + 0.5 * TERMINAL_PENALTY * c_rel * c_rel
            else:
                objective = energy
            g.append(term.constraint_m)
        else:
            objective = stage
        self.nlp = {"x": w, "p": p, "f": objective, "g": ca.vertcat(*g)}
        self.objective_fn = ca.Function("objective", [w, p], [objective])
        self.constraint_fn = ca.Function("constraints", [w, p], [ca.vertcat(*g)])
        # Bounds: thrust limits; u_k >= u_min for k >= 1 on the EMPCs (not on X_0, the measured
        # state, which may be at rest); t_d in [t_d_min, t_d_max]; t_s >= 0. All constraints g are equalities.
        lbw = np.full(self.nw, -np.inf)
        ubw = np.full(self.nw, np.inf)
        for k in range(s.horizon):
            lbw[self.u_index(k)] = -vp.reverse_max_n
            ubw[self.u_index(k)] = vp.thrust_max_n
        if s.is_empc:
            for k in range(1, s.horizon + 1):
                lbw[self.x_index(k).start] = s.u_min_mps
            lbw[self.i_time] = s.t_d_min_s / self.time_scale_s
            ubw[self.i_time] = s.t_d_max_s / self.time_scale_s
            lbw[self.i_time + 1] = 0.0
        self.lbw, self.ubw = lbw, ubw
        self.lbg = np.zeros(self.ng)
        self.ubg = np.zeros(self.ng)

    # -- parameters, guesses, warm starts ------------------------------------------------------

    @staticmethod
    def parameters(x0: np.ndarray, wp_prev: tuple[float, float], wp_active: tuple[float, float],
                   track_gate: bool, task_power_w: float,
                   tau_d: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   given: tuple[float, float] = FULL_THRUST) -> np.ndarray:
        p = np.zeros(NP)
        p[P_X0:P_X0 + NX] = x0
        p[P_PREV:P_PREV + 2] = wp_prev
        p[P_ACTIVE:P_ACTIVE + 2] = wp_active
        p[P_GATE] = 1.0 if track_gate else 0.0
        p[P_TASK] = task_power_w
        p[P_TAU:P_TAU + 3] = tau_d
        p[P_GIVEN:P_GIVEN + NU] = given
        return p

    def cruise_speed_mps(self, task_power_w: float) -> float:
        """Energy-optimal cruise u* (``costs.cruise_speed_mps``; reproduction.md, T^w row) [m/s].

        Used only for initial guesses; bounded below so that a zero task power still gives a guess.
        """
        u_star = costs.cruise_speed_mps(max(task_power_w, 0.0), self.vessel)
        return max(u_star, 10.0 * self.spec.u_min_mps)

    def cold_guess(self, p: np.ndarray) -> np.ndarray:
        """A consistent first guess: hold the cruise thrust and roll the model out from x_init."""
        s, vp = self.spec, self.vessel
        w = np.zeros(self.nw)
        x = [float(v) for v in p[P_X0:P_X0 + NX]]
        thrust = self.controller.guess_thrust(self, float(p[P_TASK]))
        tau = tuple(float(v) for v in p[P_TAU:P_TAU + 3])
        given = given_pair(*thrust, (float(p[P_GIVEN]), float(p[P_GIVEN + 1])))
        for k in range(s.horizon):
            w[self.u_index(k)] = thrust
            x = model.rk4_step(x, given, s.dt_s, vp, math, tau)
            w[self.x_index(k + 1)] = x
        if s.is_empc:
            self.guess_times(w, p)
        return w

    def guess_times(self, w: np.ndarray, p: np.ndarray) -> None:
        """Set t_d, t_s in ``w`` from its terminal state, by the terminal cost itself.

        t_d minimises E_d + E_s = P_d(t_d) t_d + P_s t_s over a log grid of [t_d_min, t_d_max], t_s
        following from eq. 15d (t_s = d / u_H - t_d sinc(Delta psi) >= 0): a turn's best duration
        depends on the vessel and its speed (the solved t_d is about 11.5 s on the paper's 0.045 m/s
        model and 1.5-2.5 s on the 1 m/s lake boat, where a 1 + 10 |Delta psi| s rule would guess
        16 s at a 90 degree switch), so no fixed seconds-per-radian rule fits both.
        """
        s, vp = self.spec, self.vessel
        task = float(p[P_TASK])
        x_h = [float(v) for v in w[self.x_index(s.horizon)]]
        term = costs.terminal_terms(x_h, 1.0, 0.0, p[P_PREV:P_PREV + 2], p[P_ACTIVE:P_ACTIVE + 2],
                                    task, 0.0, s.profile_n, vp, math)
        u_h = max(x_h[0], s.u_min_mps)
        sinc = costs.smooth_sinc(term.delta_psi_rad)
        reach_s = term.distance_m / u_h
        grid = np.geomspace(s.t_d_min_s, s.t_d_max_s, 48)
        t_s = reach_s - grid * sinc
        energy = (costs.dynamic_power_w(u_h, x_h[2], term.delta_psi_rad, grid, task, s.profile_n, vp)
                  * grid + (costs.surge_power_w(u_h, vp) + task) * np.maximum(t_s, 0.0))
        energy[t_s < 0.0] = np.inf  # eq. 15d needs t_s >= 0
        t_d = float(grid[int(np.argmin(energy))]) if np.isfinite(energy).any() else s.t_d_min_s
        w[self.i_time] = t_d / self.time_scale_s
        w[self.i_time + 1] = max(0.0, reach_s - t_d * sinc) / self.time_scale_s

    def terminal_multiplier_guess(self, w: np.ndarray, p: np.ndarray) -> float:
        """The terminal constraint's multiplier at the guess ``w``: stationarity in t_s (interior).

        d/dt_s [J / E* + lambda c] = P_s / E* + lambda u_H = 0 (the penalty's gradient is zero at a
        feasible point), so lambda = -P_s / (E* u_H); a better start than 0 after a waypoint switch.
        """
        task = float(p[P_TASK])
        u_h = max(float(w[self.x_index(self.spec.horizon).start]), self.spec.u_min_mps)
        p_static = costs.surge_power_w(u_h, self.vessel) + task
        scale = empc_objective_scale(task, self.vessel) if self.scaled else 1.0
        return -p_static * scale / u_h

    def shift(self, w: np.ndarray, lam_x: np.ndarray, lam_g: np.ndarray, tau_d: np.ndarray,
              given: tuple[float, float] = FULL_THRUST) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Shift primal and dual solutions one stage for the next warm start (solver-notes trap 5).

        Block k = [U_k, X_{k+1}] takes block k+1's values; the last control is held and the last
        state propagated with it (the thrust the thrusters give of it, ``given``; multipliers
        kept). Times keep their values, t_s less one period.
        """
        s = self.spec
        h, st = s.horizon, self.stage
        w2, lx2, lg2 = w.copy(), lam_x.copy(), lam_g.copy()
        w2[: (h - 1) * st] = w[st: h * st]
        lx2[: (h - 1) * st] = lam_x[st: h * st]
        x_last = w[self.x_index(h)]
        u_last = given_pair(*w[self.u_index(h - 1)].tolist(), given)  # x 1.0 is exact
        w2[self.x_index(h)] = model.rk4_step(x_last.tolist(), u_last, s.dt_s, self.vessel,
                                             math, tuple(np.asarray(tau_d, dtype=float).tolist()))
        # Costates: gap k takes gap k+1's multipliers; the last gap keeps its own.
        lg2[: NX * (h - 1)] = lam_g[NX: NX * h]
        if s.is_empc:
            w2[self.i_time + 1] = max(0.0, w[self.i_time + 1] - s.dt_s / self.time_scale_s)
        return w2, lx2, lg2
