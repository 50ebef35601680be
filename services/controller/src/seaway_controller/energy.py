"""The energy budget's prediction (issue #17): energy to finish the mission and to get home, from the
controller's own model and cost at its economic cruise under the estimated disturbance, and the
point of no return. Pure: states and plans in, energies out. When it is priced and what it decides
is ``seaway_controller.budget``'s.

All energies count what the paper's energy counts (eq. 3): propulsion alpha (T1^2 + T2^2) plus the
task power T^w, integrated over time [J]. Positions are local NED [m], angles from north [rad].

* **The active leg** is the MPC's own: horizon stage cost + E_d + E_s (``Costs.energy_to_go_j``).
  Two corrections make it the energy the leg really takes: E_s prices the distance to the waypoint
  itself while the leg ends on its circle of acceptance (r_COA less, at the cruise's energy per
  metre), and the terminal cost is the paper's, disturbance-free, while the cruise below is not.
* **Each later leg** starts where the vessel enters the previous circle and ends on its own: a turn
  by the change of course, priced by the paper's terminal cost (the least E_d + E_s over t_d minus
  the straight run it replaces), plus the straight run at the economic cruise. The terminal cost's
  yaw power sees only the yaw damping (N = m33 rdot + Nr r); the model the vessel turns by also
  has the sway it slips into and its Munk moment, which change the moment a turn at the cruise
  takes. The turns are priced with that moment (``seaway_controller.energy_runs.turning_vessel``):
  the MPC optimises the paper's cost, but its closed loop turns the vessel the model has.
* **The cruise** under a disturbance force (``cruise``): the estimator's tau_d, a body-frame force,
  is taken as the world-frame force it is now (wind, or a current seen through the GNSS) and turned
  into each leg's body frame. The economic controllers hold the model's surge speed at u*, where
  P^sur(u*) = T^w (their terminal cost has no disturbance): predicting with tau_d they pay for the
  disturbance in thrust (T1 + T2 = Xu u* - F_u); predicting with tau_d = 0 (the paper's) they keep
  the thrust and the speed changes (u = u* + F_u / Xu). The sway force is met by crabbing into it
  (v = F_v / Yv, heading off the course so the track is made good), its Munk and yaw moments by
  differential thrust. The NMPC has no economic cruise: it is taken at its present speed.
* **Home** is straight from here to the home point's circle: a turn from the present heading and
  one straight run, the same way (the return mission is exactly that path, ``return_request``).
* **The vehicle**: where the vessel file's prediction was measured on the vehicle it was identified
  from and found off (``seaway.vessel.energy_prediction.VEHICLES_MEASURED``: ArduPilot's SITL boat,
  whose drag and turns the identified model prices high), every energy above is scaled by that
  measured ratio (``EnergyModel.vehicle_ratio``); 1 for any other file.
* **The band** is the prediction at the disturbance one standard deviation away along each
  principal axis of the estimate's tau_d covariance: the lowest and highest of those, and the
  nominal; the energy to finish's ends are then widened by the controller's own measured
  prediction error (``seaway.vessel.energy_prediction``), so that it holds what finishing takes.

The point of no return is where along the path ahead the margin is predicted to reach 0: the
remaining energy less the energy to get there, against the energy home from there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from seaway.contract.messages import MissionAccepted, StateEstimate
from seaway.vessel.energy_prediction import forecast_ratio
from seaway.vessel.model import VesselParams

from seaway_controller import costs
from seaway_controller.energy_runs import (
    Cruise,
    _per_m,
    _turn_table,
    cruise,
    cruise_courses,
)

TABLES_PER_MODEL = 8
"""Turn tables a model keeps (one per speed): an economic mission needs one, at u*."""
PNR_SCAN = 32
"""Points along the path ahead at which the margin is first predicted for the point of no return."""
PNR_REFINE, PNR_REFINE_ROUNDS = 16, 4
"""The scan interval where the margin reaches 0 is cut in 16, four times: 2^-16 of it (a 100 m
path: to 0.05 mm)."""
MIN_SPEED_FRAC = 0.05
"""A predicted ground speed below this fraction of u* means the vessel cannot make way against the
disturbance on that course: the leg's energy is then unbounded (reported as such)."""


# -- the model of one mission ------------------------------------------------------------------------


@dataclass(frozen=True)
class Disturbance:
    """The estimated disturbance as the prediction uses it: a world-frame force and a yaw moment."""

    force_ne: tuple[float, float] = (0.0, 0.0)
    yaw_nm: float = 0.0

    @classmethod
    def from_body(cls, tau: Sequence[float], psi_rad: float) -> Disturbance:
        """tau_d = (surge [N], sway [N], yaw [N m]) at heading ``psi_rad``, as a world force."""
        c, s = math.cos(psi_rad), math.sin(psi_rad)
        return cls((c * tau[0] - s * tau[1], s * tau[0] + c * tau[1]), tau[2])


ZERO = Disturbance()


@dataclass(frozen=True)
class EnergyModel:
    """What a mission is flown with that the prediction needs."""

    vessel: VesselParams
    task_power_w: float
    coa_radius_m: float
    economic: bool
    predict_disturbance: bool
    profile_n: float = 2.0
    t_d_min_s: float = 1.0
    t_d_max_s: float = 60.0
    # This model's turn tables by speed: the shared cache's key hashes the whole vessel (a pydantic
    # model), which cost more than the lookup itself at ~100 lookups a period.
    _tables: dict[float, np.ndarray] = field(default_factory=dict, init=False,
                                                    compare=False, hash=False, repr=False)

    @classmethod
    def from_accepted(cls, accepted: MissionAccepted, vessel: VesselParams) -> EnergyModel:
        """The model of a mission as recorded (``mission/accepted`` carries its settings)."""
        cs = accepted.controller_settings
        return cls(vessel, accepted.task_power_w, accepted.coa_radius_m,
                   "t_d_min_s" in cs, accepted.predict_disturbance, cs.get("profile_n", 2.0),
                   cs.get("t_d_min_s", 1.0), cs.get("t_d_max_s", 60.0))

    @property
    def vehicle_ratio(self) -> float:
        """The measured energy used / predicted on this vessel file's vehicle (module docstring)."""
        return forecast_ratio(self.vessel.name)

    @property
    def cruise_speed_mps(self) -> float:
        """u*: P^sur(u*) = T^w (the economic controllers' cruise) [m/s]."""
        return costs.cruise_speed_mps(self.task_power_w, self.vessel)

    def speed_mps(self, state: StateEstimate | None) -> float:
        """The model surge speed the controller holds: u*, or the NMPC's present speed."""
        u_star = self.cruise_speed_mps
        if self.economic or state is None:
            return u_star
        return max(state.u_mps, MIN_SPEED_FRAC * u_star)

    def _table(self, speed_mps: float) -> np.ndarray:
        """The turn table at this speed, as the array it is interpolated in (kept as one)."""
        key = round(speed_mps, 6)
        table = self._tables.get(key)
        if table is None:
            if len(self._tables) >= TABLES_PER_MODEL:  # the NMPC's speed is new every period
                self._tables.clear()
            table = self._tables[key] = np.asarray(_turn_table(
                self.vessel, self.task_power_w, key, self.profile_n, self.t_d_min_s,
                self.t_d_max_s))
        return table

    def turn_j(self, delta_psi: float, speed_mps: float) -> float:
        """The turn's extra energy [J], interpolated in the table for this speed (per mission at
        u*; the NMPC's changes with its speed, hence the cache by speed)."""
        return float(self.turn_j_many(np.array([delta_psi]), speed_mps)[0])

    def turn_j_many(self, delta_psi: np.ndarray, speed_mps: float) -> np.ndarray:
        """``turn_j`` of each angle in ``delta_psi`` [J]."""
        table = self._table(speed_mps)
        x = np.abs(np.arctan2(np.sin(delta_psi), np.cos(delta_psi))) / math.pi * (len(table) - 1)
        i = np.minimum(x.astype(int), len(table) - 2)
        f = x - i
        return table[i] * (1.0 - f) + table[i + 1] * f

    def run_j_many(self, starts: np.ndarray, end: tuple[float, float], headings_rad: np.ndarray,
                   speed_mps: float, dist: Disturbance, shorten_m: float) -> np.ndarray:
        """Energy [J] of turning from each of ``headings_rad`` towards ``end`` and running there
        from each of ``starts`` (n x 2) [m], stopping ``shorten_m`` before it (on its circle)."""
        dx, dy = end[0] - starts[:, 0], end[1] - starts[:, 1]
        courses = np.arctan2(dy, dx)
        lengths = np.maximum(0.0, np.hypot(dx, dy) - shorten_m)
        ground, power = self.cruise_many(courses, speed_mps, [dist])
        with np.errstate(invalid="ignore"):  # inf J/m x 0 m: a run of no length, 0 J below
            j = self.turn_j_many(courses - headings_rad, speed_mps) + _per_m(ground[0], power[0]) * lengths
        j = np.where(ground[0] < MIN_SPEED_FRAC * speed_mps, np.inf, j)
        return np.where(lengths == 0.0, 0.0, j)

    def cruise_many(self, courses_rad: np.ndarray, speed_mps: float,
                    dists: Sequence[Disturbance]) -> tuple[np.ndarray, np.ndarray]:
        """(ground speeds [m/s], powers [W]) of the cruise along each course under each
        disturbance: arrays of len(dists) x len(courses)."""
        fn = np.array([[d.force_ne[0]] for d in dists])
        fe = np.array([[d.force_ne[1]] for d in dists])
        yaw = np.array([[d.yaw_nm] for d in dists])
        ground, power, _, _ = cruise_courses(self.vessel, self.task_power_w, speed_mps,
                                             np.asarray(courses_rad), fn, fe, yaw,
                                             pay_in_thrust=self.predict_disturbance)
        return ground, power

    def cruise(self, course_rad: float, speed_mps: float, dist: Disturbance) -> Cruise:
        return cruise(self.vessel, self.task_power_w, speed_mps, course_rad, dist.force_ne,
                      dist.yaw_nm, pay_in_thrust=self.predict_disturbance)


@dataclass(frozen=True)
class Prediction:
    """One prediction of the energy to finish and to get home [J]."""

    to_go_j: float
    to_home_j: float


def predict(model: EnergyModel, state: StateEstimate, waypoints: Sequence[tuple[float, float]],
            active: int, home: tuple[float, float], leg_mpc_j: float | None,
            dist: Disturbance) -> Prediction:
    """Energy to finish (from the active leg ``active`` on) and straight home, from ``state``.

    ``leg_mpc_j`` is the MPC's energy to the active waypoint (None: no plan; the active leg is then
    priced like the later ones)."""
    return predict_many(model, state, waypoints, active, home, leg_mpc_j, [dist])[0]


def predict_many(model: EnergyModel, state: StateEstimate,
                 waypoints: Sequence[tuple[float, float]], active: int,
                 home: tuple[float, float], leg_mpc_j: float | None,
                 dists: Sequence[Disturbance]) -> list[Prediction]:
    """``predict`` under each of ``dists``. The runs' geometry (courses, lengths, turns) does not
    depend on the disturbance; only their cruise does, priced for all at once."""
    pos, heading = (state.x_m, state.y_m), state.psi_rad
    speed = model.speed_mps(state)
    r = model.coa_radius_m
    # The runs: the active leg, the later ones (each from where the vessel enters the previous
    # circle, on its way in), and straight home; each as (course, length, heading before it).
    runs: list[tuple[float, float, float]] = []

    def run(start: tuple[float, float], end: tuple[float, float], from_rad: float) -> float:
        dx, dy = end[0] - start[0], end[1] - start[1]
        course = math.atan2(dy, dx)
        runs.append((course, max(0.0, math.hypot(dx, dy) - r), from_rad))
        return course

    target = waypoints[active]
    course = run(pos, target, heading)
    entry = _entry(pos, target, r)
    for nxt in waypoints[active + 1:]:
        course = run(entry, nxt, course)
        entry = _entry(entry, nxt, r)
    run(pos, home, heading)
    courses, lengths, before = np.array(runs).T
    turns = model.turn_j_many(courses - before, speed)
    # Row 0 undisturbed (the MPC's figure is corrected from it), then one row per disturbance.
    ground, power = model.cruise_many(courses, speed, [ZERO, *dists])
    per_m = _per_m(ground, power)
    with np.errstate(invalid="ignore"):  # inf J/m x 0 m: a run of no length, 0 J just below
        energy = turns + per_m[1:] * lengths
    energy = np.where(ground[1:] < MIN_SPEED_FRAC * speed, np.inf, energy)
    energy = np.where(lengths == 0.0, 0.0, energy)  # (D x runs) [J]
    if leg_mpc_j is not None:
        # The MPC's figure for the active leg, corrected to the circle and to the disturbed cruise
        # (module docstring).
        remaining = max(0.0, math.dist(pos, target) - r)
        undisturbed = per_m[0, 0]
        near = undisturbed * min(r, math.dist(pos, target))
        mpc = leg_mpc_j - near + (per_m[1:, 0] - undisturbed) * remaining
        energy[:, 0] = np.where(np.isfinite(energy[:, 0]), mpc, energy[:, 0])
    energy = energy * model.vehicle_ratio
    to_go, to_home = energy[:, :-1].sum(axis=1), energy[:, -1]
    return [Prediction(float(g), float(h)) for g, h in zip(to_go, to_home, strict=True)]


def _entry(start: tuple[float, float], target: tuple[float, float], r: float) -> tuple[float, float]:
    """Where a run from ``start`` to ``target`` enters the circle of radius r around it."""
    d = math.dist(start, target)
    if d <= r:
        return start
    f = (d - r) / d
    return (start[0] + f * (target[0] - start[0]), start[1] + f * (target[1] - start[1]))


def disturbance_sigma_points(state: StateEstimate) -> tuple[Disturbance, list[Disturbance]]:
    """The nominal disturbance and the ones a standard deviation away along each principal axis of
    the estimate's tau_d covariance (none without a covariance)."""
    # Plain floats where numpy scalars would do the same IEEE operations at a larger cost.
    tau = [state.tau_d_surge_n, state.tau_d_sway_n, state.tau_d_yaw_nm]
    nominal = Disturbance.from_body(tau, state.psi_rad)
    if state.covariance is None:
        return nominal, []
    c = state.covariance  # row-major 9 x 9; tau_d's block is rows and columns 6..8
    cov = np.array([c[60:63], c[69:72], c[78:81]], dtype=float)
    cov = 0.5 * (cov + cov.T)
    vals, vecs = np.linalg.eigh(cov)
    out = []
    for k, val in enumerate(vals.tolist()):
        if val <= 0:
            continue
        step = (math.sqrt(val) * vecs[:, k]).tolist()
        out += [Disturbance.from_body([a + b for a, b in zip(tau, step, strict=True)],
                                      state.psi_rad),
                Disturbance.from_body([a - b for a, b in zip(tau, step, strict=True)],
                                      state.psi_rad)]
    return nominal, out


# -- the point of no return ---------------------------------------------------------------------------


def no_return_point(model: EnergyModel, state: StateEstimate,
                    waypoints: Sequence[tuple[float, float]], active: int,
                    home: tuple[float, float], remaining_j: float, reserve_j: float,
                    dist: Disturbance) -> tuple[float, float, float] | None:
    """(x [m], y [m], distance along the path [m]) where the margin is predicted to reach 0 along
    the path ahead, or None if it does not before the mission ends (or already has).

    The margin is scanned at ``PNR_SCAN`` points along the path, then the first interval where it
    reaches 0 is cut in ``PNR_REFINE`` parts ``PNR_REFINE_ROUNDS`` times. Each scan prices all its
    runs home at once (``EnergyModel.run_j_many``): the controller does this every period, and one
    run at a time it cost more than the MPC's solve."""
    speed = model.speed_mps(state)
    r = model.coa_radius_m
    # The path ahead as segments: start point, unit direction, course, length, and the heading
    # before it (its turn); then the distance along the path and the energy spent at each start.
    starts, units, courses, lengths, before = [], [], [], [], []
    start, heading = (state.x_m, state.y_m), state.psi_rad
    for wp in waypoints[active:]:
        end = _entry(start, wp, r)
        length = math.dist(start, end)
        if length > 0:
            course = math.atan2(end[1] - start[1], end[0] - start[0])
            starts.append(start)
            units.append(((end[0] - start[0]) / length, (end[1] - start[1]) / length))
            courses.append(course)
            lengths.append(length)
            before.append(heading)
            heading = course
        start = end
    if not lengths:
        return None
    seg_start, seg_unit, seg_course = np.array(starts), np.array(units), np.array(courses)
    seg_len = np.array(lengths)
    seg_per_m = _per_m(*model.cruise_many(seg_course, speed, [dist]))[0]
    turns = model.turn_j_many(seg_course - np.array(before), speed)
    seg_s0 = np.concatenate(([0.0], np.cumsum(seg_len)[:-1]))
    # Energy spent at each segment's start, its turn included: the turns and runs before it.
    seg_e0 = np.cumsum(turns) + np.concatenate(([0.0], np.cumsum(seg_per_m * seg_len)[:-1]))
    total = float(seg_len.sum())

    ratio = model.vehicle_ratio

    def at(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(margins [J], points (n x 2) [m]) at distances ``s`` [m] along the path."""
        k = np.maximum(np.searchsorted(seg_s0, s, side="right") - 1, 0)
        along = (s - seg_s0[k])[:, None]
        q = seg_start[k] + seg_unit[k] * along
        home_j = model.run_j_many(q, home, seg_course[k], speed, dist, r)
        spent_j = seg_e0[k] + seg_per_m[k] * along[:, 0]
        return remaining_j - ratio * (spent_j + home_j) - reserve_j, q

    def first_reached(s: np.ndarray) -> int | None:
        """Index of the first of ``s`` where the margin is not above 0 (NaN-safe: a path home that
        cannot be made counts as reached), or None."""
        hit = np.flatnonzero(~(at(s)[0] > 0))
        return int(hit[0]) if hit.size else None

    scan = total * np.arange(1, PNR_SCAN + 1) / PNR_SCAN
    i = first_reached(scan)
    if i is None:
        return None
    lo, hi = (scan[i - 1] if i > 0 else 0.0), scan[i]
    for _ in range(PNR_REFINE_ROUNDS):
        inner = lo + (hi - lo) * np.arange(1, PNR_REFINE) / PNR_REFINE
        j = first_reached(inner)
        if j is None:
            lo = inner[-1]
        else:
            lo, hi = (inner[j - 1] if j > 0 else lo), inner[j]
    # The point only (its margin was found above): as ``at`` places it.
    k = max(int(np.searchsorted(seg_s0, hi, side="right")) - 1, 0)
    q = seg_start[k] + seg_unit[k] * (hi - seg_s0[k])
    return float(q[0]), float(q[1]), float(hi)


# -- the budget of one mission, period after period --------------------------------------------------


def finite_or_none(v: float | None) -> float | None:
    """``v``, or None when it is None, infinite or NaN: a message's optional figure (JSON has no
    infinity, and "no figure" reads better than one that is not a number)."""
    return v if v is not None and math.isfinite(v) else None
