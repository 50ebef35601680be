"""Scenario files (``deploy/scenarios/*.toml``) and the disturbance fields they describe.

A scenario fixes everything a simulated run depends on: the vessel file, the start pose, the
disturbances, the sensor noise, the seed and, optionally, the mission. The same scenario and seed give
the same run, bit for bit: every random draw comes from ``numpy.random.Generator(PCG64(seed))``
streams derived from the seed in a fixed order.

Disturbances (summed when several are given):

* ``body_constant``: a constant force/moment in the body frame (paper condition #2);
* ``world_constant``: a constant force in the world frame, rotated into the body frame with the
  heading (conditions #3, #4);
* ``world_grid``: a world-frame force field on a rectilinear grid, bilinear inside, clamped to the
  edge values outside (condition #5, ``shared/reproduction/condition5_grid.json``);
* ``current``: a water current (uniform) that carries the vessel (it enters the kinematics, not the
  forces; see ``seaway.vessel.model``);
* ``wind``: a mean wind with seeded gusts (a first-order Gauss-Markov process on speed and
  direction), turned into a world-frame force by a quadratic drag law.

Faults (``[[faults]]``: GNSS dropouts, position jumps, heading biases, thruster failures) are
scheduled at fixed times of the scenario: ``seaway.simkit.faults``.

World x/y are NED north/east, as the waypoints are (shared/reproduction.md).
"""

from __future__ import annotations

import bisect
import itertools
import json
import math
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, model_validator

from seaway.area.model import AreaError, OperatingArea
from seaway.area.spec import AreaSpec
from seaway.contract.config import (
    ConfigError,
    ConfigModel,
    Origin,
    deploy_named,
    parse_config,
    read_document,
    unreadable,
)
from seaway.contract.messages import MAX_ATTITUDE_RATE_HZ, MAX_GNSS_RATE_HZ, MAX_GNSS_STD_M
from seaway.contract.missions import MissionSpec
from seaway.contract.units import finite_number
from seaway.simkit.faults import Fault, jumps_too_far
from seaway.vessel.battery import BatteryParams
from seaway.vessel.frames import MAX_RANGE_M, GeoOrigin
from seaway.vessel.model import world_to_body

AIR_DENSITY_KGPM3 = 1.225

# Bounds on what a scenario may ask of the simulated world: beyond any sea a small twin-thruster
# vessel works in, inside what the plant and its sensors can represent for every vessel file in
# deploy/vessels (the lightest, 2 kg, stays finite at all of them at once: a unit test). Without
# them a valid file (a current of 10^5 m/s, a wind of 10^6 m/s) crashed the sim at its first step
# (a GNSS speed over MAVLink's 16 bits, a heading of inf), and a scenario loaded at run time and
# kept in the sim's state file crashed it again at each restart. A heavier vessel could take more;
# a lighter one than 2 kg may need lower bounds (the test runs every vessel file at them).
MAX_FORCE_N = 50.0
"""A constant or gridded disturbance force, each component [N] (the paper's are under 0.1 N)."""
MAX_MOMENT_NM = 2.0
"""A constant disturbance yaw moment [N m]."""
MAX_CURRENT_MPS = 5.0
"""A current, each component [m/s]: the strongest tidal races run about 5 m/s."""
MAX_WIND_MPS = 25.0
"""Mean wind speed [m/s]: a storm (Beaufort 10, 24.5-28.4 m/s)."""
MAX_GUST_STD_MPS = 10.0
"""Gust speed standard deviation [m/s]."""
MAX_DRAG_AREA_M2 = 0.25
"""Above-water Cd * A [m^2]: the paper's lake scenario has 0.08."""
MAX_START_RANGE_M = MAX_RANGE_M
"""How far from the NED origin a run may start, each axis [m]: anywhere in the local frame
(``seaway.vessel.frames.MAX_RANGE_M``)."""
MAX_START_SPEED_MPS = 20.0
"""Start surge speed, either way [m/s]."""
MAX_START_HEADING_RAD = 1000.0
"""Start heading, either way [rad]: any heading, wrapped, but not one so large that a float loses
its angle."""


def _within(bound: float) -> Any:
    """A float field bounded to [-bound, bound], default 0."""
    return Field(default=0.0, ge=-bound, le=bound)


class BodyConstant(ConfigModel):
    kind: Literal["body_constant"]
    surge_n: float = _within(MAX_FORCE_N)
    sway_n: float = _within(MAX_FORCE_N)
    yaw_nm: float = _within(MAX_MOMENT_NM)


class WorldConstant(ConfigModel):
    kind: Literal["world_constant"]
    north_n: float = _within(MAX_FORCE_N)
    east_n: float = _within(MAX_FORCE_N)


class WorldGrid(ConfigModel):
    """Force field on a grid: ``north_n[i][j]``, ``east_n[i][j]`` at (xs_m[i], ys_m[j])."""

    kind: Literal["world_grid"]
    xs_m: list[float] = Field(min_length=2)
    ys_m: list[float] = Field(min_length=2)
    north_n: list[list[float]]
    east_n: list[list[float]]

    @model_validator(mode="after")
    def _shape(self) -> WorldGrid:
        for name, axis in (("xs_m", self.xs_m), ("ys_m", self.ys_m)):
            if any(b <= a for a, b in itertools.pairwise(axis)):
                raise ValueError(f"{name} must be strictly increasing")
        for name, table in (("north_n", self.north_n), ("east_n", self.east_n)):
            if len(table) != len(self.xs_m) or any(len(row) != len(self.ys_m) for row in table):
                raise ValueError(f"{name} must be {len(self.xs_m)} rows of {len(self.ys_m)} values "
                                 "(one row per xs_m, one value per ys_m)")
            if len(self.xs_m) * len(self.ys_m) > MAX_GRID_POINTS:
                raise ValueError(f"{len(self.xs_m)} x {len(self.ys_m)} points, at most "
                                 f"{MAX_GRID_POINTS} in all")
            if any(abs(f) > MAX_FORCE_N for row in table for f in row):
                raise ValueError(f"{name}: every force must be within +-{MAX_FORCE_N:g} N")
        return self


class Current(ConfigModel):
    kind: Literal["current"]
    north_mps: float = _within(MAX_CURRENT_MPS)
    east_mps: float = _within(MAX_CURRENT_MPS)


class Wind(ConfigModel):
    """Wind from ``from_rad`` (meteorological: the direction it blows from, clockwise from north)."""

    kind: Literal["wind"]
    speed_mps: float = Field(ge=0, le=MAX_WIND_MPS)
    from_rad: float
    drag_area_m2: float = Field(default=0.05, ge=0, le=MAX_DRAG_AREA_M2,
                                description="Cd * A, above-water [m^2]")
    gust_std_mps: float = Field(default=0.0, ge=0, le=MAX_GUST_STD_MPS,
                                description="gust speed std [m/s]")
    gust_direction_std_rad: float = Field(default=0.0, ge=0, le=math.pi,
                                          description="gust direction std [rad]; at most half a "
                                          "turn, any direction (a larger one wraps to the same)")
    gust_time_constant_s: float = Field(default=5.0, gt=0)


Disturbance = Annotated[BodyConstant | WorldConstant | WorldGrid | Current | Wind,
                        Field(discriminator="kind")]

# Disturbances of one kind add: 200 currents of 5 m/s each, each within its bound, were a valid
# scenario, and the sim died packing a GNSS speed of 1400 m/s into MAVLink's 16 bits (200 world
# forces of 50 N: a NaN heading at the 4th step). So the sum of each kind is held to what one entry
# may be (the tested worst case stays the worst case), and the lists are bounded.
MAX_DISTURBANCES = 64
"""Entries of ``[[disturbances]]``: each is evaluated at every plant step; the shipped scenarios
list at most two."""
MAX_FAULTS = 1000
"""Entries of ``[[faults]]``: each is looked at for every sample and step; the shipped scenarios
list at most six."""
MAX_GRID_POINTS = 1_000_000
"""Points of one ``world_grid`` (rows x columns): held in memory and in the sim's state file."""
GUST_SIGMAS = 3.0
"""Gusts counted at this many standard deviations when the winds' strength is summed."""
MAX_WIND_STRENGTH_M4PS2 = MAX_DRAG_AREA_M2 * (MAX_WIND_MPS + GUST_SIGMAS * MAX_GUST_STD_MPS) ** 2
"""Cd*A (speed + 3 gust std)^2 [m^4/s^2] of the strongest wind allowed: the bound on all the winds
of a scenario together (a wind's force over half the air density)."""


def disturbance_sums(ds: list[Any]) -> list[tuple[str, float, float, str]]:
    """(field, total over the entries, bound, unit) of each quantity that adds across ``ds``."""
    def of(kind: type) -> list[Any]:
        return [d for d in ds if isinstance(d, kind)]

    def peak_n(table: list[list[float]]) -> float:
        return max((abs(f) for row in table for f in row), default=0.0)

    cur, body, world, grids = of(Current), of(BodyConstant), of(WorldConstant), of(WorldGrid)
    winds = of(Wind)
    return [
        ("current north_mps", sum(abs(d.north_mps) for d in cur), MAX_CURRENT_MPS, "m/s"),
        ("current east_mps", sum(abs(d.east_mps) for d in cur), MAX_CURRENT_MPS, "m/s"),
        ("body_constant surge_n", sum(abs(d.surge_n) for d in body), MAX_FORCE_N, "N"),
        ("body_constant sway_n", sum(abs(d.sway_n) for d in body), MAX_FORCE_N, "N"),
        ("body_constant yaw_nm", sum(abs(d.yaw_nm) for d in body), MAX_MOMENT_NM, "N m"),
        ("world_constant and world_grid north_n", sum(abs(d.north_n) for d in world)
         + sum(peak_n(g.north_n) for g in grids), MAX_FORCE_N, "N"),
        ("world_constant and world_grid east_n", sum(abs(d.east_n) for d in world)
         + sum(peak_n(g.east_n) for g in grids), MAX_FORCE_N, "N"),
        ("wind drag_area_m2 * (speed_mps + 3 gust_std_mps)^2",
         sum(w.drag_area_m2 * (w.speed_mps + GUST_SIGMAS * w.gust_std_mps) ** 2 for w in winds),
         MAX_WIND_STRENGTH_M4PS2, "m^4/s^2"),
    ]


# Bounds on the simulated sensors: physically a poor sensor at most, and inside the MAVLink fields
# the samples end up in: past them a file would crash the sim at its first samples (a speed std
# of 10^5 m/s over GPS_RAW_INT's uint16 cm/s, a position std of 10^7 m over its uint32 mm h_acc,
# a yaw rate over a float32) or at its start (a rate of 10^-300 Hz: an infinite period), and
# outages starting 10^300 times a second would hang it.
MIN_SENSOR_RATE_HZ = 0.1
"""The slowest GNSS or attitude rate [Hz]: one sample every 10 s (a period of whole nanoseconds)."""
MAX_SOG_STD_MPS = 5.0
"""GNSS velocity over ground std per axis [m/s]: the speeds the vessels go."""
MAX_HEADING_STD_RAD = math.pi
"""Heading std [rad]: half a turn, any heading (it is wrapped)."""
MAX_YAW_RATE_STD_RADPS = 1.0
"""Yaw rate std [rad/s]: a gyro worse than that is none."""
MAX_DROPOUT_RATE_PER_S = 10.0
"""GNSS outage starts a second, on average [1/s]: the sim steps through every outage, so this bounds
that work to about ten a simulated second; outages starting more
often are a receiver that is off, not one dropping out."""
MAX_DROPOUT_DURATION_S = 3600.0
"""One GNSS outage [s]: an hour; a receiver out for longer is gone, not dropping out."""


class SensorNoise(ConfigModel):
    """Sensor models of the simulated autopilot; std values are 1-sigma, white, seeded."""

    gnss_rate_hz: float = Field(default=5.0, ge=MIN_SENSOR_RATE_HZ, le=MAX_GNSS_RATE_HZ,
                                description="[Hz]")
    gnss_std_m: float = Field(default=0.0, ge=0, le=MAX_GNSS_STD_M,
                              description="horizontal position std, north and east each [m]")
    gnss_dropout_rate_per_s: float = Field(default=0.0, ge=0, le=MAX_DROPOUT_RATE_PER_S,
                                           description="Poisson dropout starts [1/s]")
    gnss_dropout_duration_s: float = Field(default=0.0, ge=0, le=MAX_DROPOUT_DURATION_S,
                                           description="each dropout's length [s]")
    heading_std_rad: float = Field(default=0.0, ge=0, le=MAX_HEADING_STD_RAD, description="[rad]")
    yaw_rate_std_radps: float = Field(default=0.0, ge=0, le=MAX_YAW_RATE_STD_RADPS,
                                      description="[rad/s]")
    sog_std_mps: float = Field(default=0.0, ge=0, le=MAX_SOG_STD_MPS,
                               description="velocity over ground std, north and east each [m/s]")
    attitude_rate_hz: float = Field(default=20.0, ge=MIN_SENSOR_RATE_HZ, le=MAX_ATTITUDE_RATE_HZ,
                                    description="[Hz]")


class StartPose(ConfigModel):
    x_m: float = _within(MAX_START_RANGE_M)
    y_m: float = _within(MAX_START_RANGE_M)
    psi_rad: float = _within(MAX_START_HEADING_RAD)
    u_mps: float = _within(MAX_START_SPEED_MPS)


def load_mission(path: str | Path) -> MissionSpec:
    """A mission file, or the ``[mission]`` table of a scenario file (by path or scenario name)."""
    return load_mission_source(path)[0]


def load_mission_source(path: str | Path) -> tuple[MissionSpec, Scenario | None]:
    """``load_mission``, and the scenario it is the ``[mission]`` of (parsed whole: every table
    checked), or None for a mission file."""
    p = Path(path)
    if p.suffix not in (".toml", ".json"):
        sc = load_scenario(path)
    else:
        doc = read_document(p)
        if not ("mission" in doc and isinstance(doc["mission"], dict)):
            return parse_config(doc, MissionSpec, str(p)), None
        sc = parse_scenario(doc, str(p), p.parent)
    if sc.mission is None:
        raise ConfigError(f"scenario {sc.name!r} has no [mission]")
    return sc.mission.model_copy(update={"mission_id": sc.mission.mission_id or sc.name}), sc


class ScenarioBattery(ConfigModel):
    """A scenario's ``[battery]``: how the simulated pack starts and what else draws from it. The
    pack itself is the plant vessel file's ``[battery]`` (``seaway.vessel.battery``)."""

    def start_j(self, pack: BatteryParams | None) -> float | None:
        """The usable energy at the start [J]: ``initial_energy_j``, else the full ``pack``'s;
        None: neither known (what a mission is checked against before any battery report)."""
        if self.initial_energy_j is not None:
            return self.initial_energy_j
        return None if pack is None else pack.energy_j

    initial_energy_j: float | None = Field(default=None, ge=0, description="usable energy in the "
                                           "pack at the start [J]; default full")
    hotel_power_w: float | None = Field(default=None, ge=0, description="power drawn besides the "
                                        "thrusters [W]; default the scenario mission's task power "
                                        "T^w (0 without a mission)")


class Scenario(ConfigModel):
    name: str = Field(min_length=1)
    description: str = ""
    seed: int = Field(ge=0)
    vessel: str = Field(min_length=1, description="vessel file name (deploy/vessels) or path: the "
                        "model the estimator and controller use, and the plant unless plant_vessel")
    plant_vessel: str | None = Field(default=None, description="vessel file the simulator integrates "
                                     "when it differs from the model (robustness runs); default vessel")
    start: StartPose = StartPose()
    origin: Origin = Origin()
    disturbances: list[Disturbance] = Field(default_factory=list, max_length=MAX_DISTURBANCES)
    sensors: SensorNoise = SensorNoise()
    dead_zone: bool = Field(default=False, description="apply the vessel file's thrust dead zone")
    thruster_lag: bool = Field(default=False, description="apply the vessel file's thruster lag")
    mission: MissionSpec | None = None
    battery: ScenarioBattery = ScenarioBattery()
    faults: list[Fault] = Field(default_factory=list, max_length=MAX_FAULTS,
                                description="scheduled sensor and thruster faults "
                                "(seaway.simkit.faults)")
    area: AreaSpec | None = Field(default=None, description="the operating area and rally points "
                                  "(seaway.area.spec; degrees through [origin]); the start and the "
                                  "mission's home must be inside it")

    @model_validator(mode="after")
    def _disturbances_together(self) -> Scenario:
        over = [f"{field} adds up to {total:g} {unit} over the entries, at most {bound:g} {unit} "
                "(what one entry may be: disturbances of one kind add)"
                for field, total, bound, unit in disturbance_sums(self.disturbances) if total > bound]
        if over:
            raise ValueError("disturbances: " + "; ".join(over))
        return self

    @model_validator(mode="after")
    def _jumps_together(self) -> Scenario:
        problem = jumps_too_far(self.faults, 1.0 / self.sensors.gnss_rate_hz)
        if problem is not None:
            raise ValueError(f"faults: {problem}")
        return self

    @model_validator(mode="after")
    def _area_holds_the_start(self) -> Scenario:
        try:
            area = self.operating_area()
            if area is not None:
                area.require_inside((self.start.x_m, self.start.y_m), "start")
                if self.mission is not None and self.mission.home_m is not None:
                    area.require_inside(self.mission.home_m, "mission.home_m")
        except AreaError as err:  # one line: the area's own problems, each naming its field
            raise ValueError(str(err).replace("\n  ", "; ")) from None
        return self

    def operating_area(self) -> OperatingArea | None:
        """The scenario's operating area in local NED metres, or None; AreaError if it is not
        valid (a parsed Scenario's always is)."""
        if self.area is None:
            return None
        return self.area.to_area(GeoOrigin.from_degrees(self.origin.lat_deg, self.origin.lon_deg,
                                                        self.origin.alt_m), "area")

    @property
    def hotel_power_w(self) -> float:
        """What the simulated pack feeds besides the thrusters [W] (``ScenarioBattery``)."""
        if self.battery.hotel_power_w is not None:
            return self.battery.hotel_power_w
        return self.mission.task_power_w if self.mission is not None else 0.0

    @property
    def plant_vessel_file(self) -> str:
        """The vessel file the simulator integrates: ``plant_vessel``, else the model's ``vessel``."""
        return self.plant_vessel or self.vessel


GRID_FIELDS = ("xs_m", "ys_m", "north_n", "east_n")
"""What a ``world_grid`` entry's ``file`` gives; an entry with a file may not also give them."""


def _resolve_grid_files(doc: dict, base: Path, where: str = "scenario") -> dict:
    """``{kind = "world_grid", file = "x.json"}`` -> the grid inline (xs, ys, tx, ty as in shared/).

    ConfigError naming ``where``, the entry's field and what is allowed: a ``file`` that is not a
    path, a file that is not UTF-8 JSON, a ``scale`` that is not a number, or grid values given
    beside the file (which gives the whole grid)."""
    out = dict(doc)
    dists = []
    for i, d in enumerate(doc.get("disturbances", []) or []):
        if isinstance(d, dict) and d.get("kind") == "world_grid" and "file" in d:
            at = f"{where}: disturbances.{i}"
            if not isinstance(d["file"], str) or not d["file"]:
                raise ConfigError(f"{at}.file: {d['file']!r} is not a file's path; give the grid's "
                                  "JSON file as a string, relative to the scenario file")
            inline = [k for k in GRID_FIELDS if k in d]
            if inline:
                raise ConfigError(f"{at}: {', '.join(inline)} given beside file {d['file']!r}, which "
                                  "gives the whole grid; give either the file or the grid inline")
            scale = d.get("scale", 1.0)
            if finite_number(scale) is None:
                raise ConfigError(f"{at}.scale: {scale!r} is not a finite number (the factor the "
                                  "file's forces are multiplied by)")
            path = (base / d["file"]).resolve()
            try:
                grid = json.loads(path.read_text(encoding="utf-8"))
            except OSError as err:
                raise ConfigError(f"{at}.file: {path}: cannot read: {err.strerror or err}") from None
            except UnicodeDecodeError as err:
                raise ConfigError(f"{at}.file: {path}: not UTF-8 text (byte {err.start} is "
                                  f"0x{err.object[err.start]:02x}); a grid file is UTF-8 JSON") from None
            except json.JSONDecodeError as err:
                raise ConfigError(f"{at}.file: {path}: not valid JSON: {err}") from None
            except (ValueError, RecursionError) as err:
                raise ConfigError(f"{at}.file: {path}: {unreadable(err)}") from None
            rest = {k: v for k, v in d.items() if k not in ("file", "scale")}
            try:
                d = {**rest, "xs_m": grid["xs"], "ys_m": grid["ys"],
                     "north_n": [[scale * v for v in row] for row in grid["tx"]],
                     "east_n": [[scale * v for v in row] for row in grid["ty"]]}
            except (KeyError, TypeError) as err:
                raise ConfigError(f"{at}.file: {path}: needs xs, ys, tx, ty ({err})") from None
        dists.append(d)
    if "disturbances" in doc:
        out["disturbances"] = dists
    return out


def parse_scenario(doc: dict, where: str = "scenario", base: Path | None = None) -> Scenario:
    """Validate a scenario document; grid ``file`` entries resolve relative to ``base``."""
    if not isinstance(doc, dict):
        raise ConfigError(f"{where}: a scenario must be a table/object")
    return parse_config(_resolve_grid_files(doc, base or Path.cwd(), where), Scenario, where)


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load ``deploy/scenarios/<name>.toml`` or a path."""
    p = deploy_named("scenarios", name_or_path, "scenario")
    return parse_scenario(read_document(p), str(p), p.parent)


# ---------------------------------------------------------------------------------------------
# Evaluating the fields
# ---------------------------------------------------------------------------------------------


def bilinear(grid: WorldGrid, x_m: float, y_m: float) -> tuple[float, float]:
    """World force (north, east) [N] at (x, y): bilinear inside the grid, clamped outside."""
    xs, ys = grid.xs_m, grid.ys_m
    x = min(max(x_m, xs[0]), xs[-1])
    y = min(max(y_m, ys[0]), ys[-1])
    i = min(max(bisect.bisect_right(xs, x) - 1, 0), len(xs) - 2)
    j = min(max(bisect.bisect_right(ys, y) - 1, 0), len(ys) - 2)
    tx = (x - xs[i]) / (xs[i + 1] - xs[i])
    ty = (y - ys[j]) / (ys[j + 1] - ys[j])

    def interp(t: list[list[float]]) -> float:
        return ((1 - tx) * (1 - ty) * t[i][j] + tx * (1 - ty) * t[i + 1][j]
                + (1 - tx) * ty * t[i][j + 1] + tx * ty * t[i + 1][j + 1])

    return interp(grid.north_n), interp(grid.east_n)


class DisturbanceModel:
    """The disturbances of one scenario, evaluated along a run.

    ``sample(t_s, x_m, y_m)`` is called once per simulator step in time order; it advances the gust
    processes (seeded) and returns what acts over the step::

        (tau_body (surge N, sway N, yaw N m), force_ne (north N, east N), current_ne (m/s, m/s))

    World-frame forces are returned in the world frame: ``seaway.vessel.model`` rotates them with the heading
    of each RK4 stage.
    """

    def __init__(self, disturbances: list, seed: int) -> None:
        self.items = list(disturbances)
        self._rng = np.random.Generator(np.random.PCG64([seed, 0xD157]))
        self._gust = [(0.0, 0.0) for _ in self.items]
        self._t_last: float | None = None

    def sample(self, t_s: float, x_m: float, y_m: float) -> tuple[
            tuple[float, float, float], tuple[float, float], tuple[float, float]]:
        dt = 0.0 if self._t_last is None else max(0.0, t_s - self._t_last)
        self._t_last = t_s
        su = sv = sr = fn = fe = cn = ce = 0.0
        for k, d in enumerate(self.items):
            if isinstance(d, BodyConstant):
                su += d.surge_n
                sv += d.sway_n
                sr += d.yaw_nm
            elif isinstance(d, WorldConstant):
                fn += d.north_n
                fe += d.east_n
            elif isinstance(d, WorldGrid):
                gn, ge = bilinear(d, x_m, y_m)
                fn += gn
                fe += ge
            elif isinstance(d, Current):
                cn += d.north_mps
                ce += d.east_mps
            elif isinstance(d, Wind):
                wn, we = self._wind_force(k, d, dt)
                fn += wn
                fe += we
        return (su, sv, sr), (fn, fe), (cn, ce)

    def _wind_force(self, k: int, d: Wind, dt: float) -> tuple[float, float]:
        gs, gd = self._gust[k]
        if dt > 0 and (d.gust_std_mps > 0 or d.gust_direction_std_rad > 0):
            # Exact discretisation of an Ornstein-Uhlenbeck process with stationary std sigma.
            a = math.exp(-dt / d.gust_time_constant_s)
            b = math.sqrt(1.0 - a * a)
            n1, n2 = self._rng.standard_normal(2)
            gs = a * gs + b * d.gust_std_mps * float(n1)
            gd = a * gd + b * d.gust_direction_std_rad * float(n2)
            self._gust[k] = (gs, gd)
        speed = max(0.0, d.speed_mps + gs)
        towards = d.from_rad + gd + math.pi  # the air moves away from where it blows from
        q = 0.5 * AIR_DENSITY_KGPM3 * d.drag_area_m2 * speed * speed
        return q * math.cos(towards), q * math.sin(towards)


def body_force(tau_body: tuple[float, float, float], force_ne: tuple[float, float],
               psi_rad: float) -> tuple[float, float, float]:
    """Total disturbance in the body frame at heading ``psi`` (what ``sim/disturbance`` reports)."""
    wu, wv = world_to_body(force_ne[0], force_ne[1], math.cos(psi_rad), math.sin(psi_rad))
    return tau_body[0] + wu, tau_body[1] + wv, tau_body[2]
