"""What a whole scenario may ask of the sim: its disturbances together, and how many it lists.

``seaway.simkit.scenario`` bounds each disturbance on its own (``MAX_*``), and its unit test shows
the plant finite and its MAVLink telemetry packable at one of each kind at the bounds. But
disturbances of one kind add: 200 currents of 5 m/s each were a valid scenario, accepted over the
bus (``sim/scenario``, action ``load``) and kept for a restart, and the sim died 10 ms later packing
a GNSS speed of 1400 m/s into MAVLink's 16 bits; kept in its state file, it died again at every
restart. Here the sum of each kind is held to what one disturbance of that kind may be, so the
tested worst case stays the worst case; and the lists are bounded, so a scenario cannot make each
step of a real-time sim (10 ms) loop over a million entries.

``check_world`` raises ConfigError naming the scenario, the field, the total and the bound; the sim
applies it to the run's scenario at start, to a document loaded over the bus before anything
changes (the request is refused, the running world untouched) and to a kept one at a restart.
"""

from __future__ import annotations

from seaway.contract.config import ConfigError
from seaway.simkit import scenario as sc

MAX_DISTURBANCES = 64
"""Entries of ``[[disturbances]]`` [count]: each is evaluated at every plant step; the shipped
scenarios list at most two."""
MAX_FAULTS = 1000
"""Entries of ``[[faults]]`` [count]: each is looked at for every sample and step; the shipped
scenarios list at most six."""
MAX_GRID_POINTS = 1_000_000
"""Points of one ``world_grid`` (rows x columns) [count]: held in memory and in the sim's state
file; the paper's condition-5 grid is far smaller."""
GUST_SIGMAS = 3.0
"""Gusts counted at this many standard deviations when the winds' strength is summed."""


def _wind_strength_m4ps2(w: sc.Wind) -> float:
    """Cd*A * (mean speed + 3 gust std)^2 [m^4/s^2]: the wind's force over half the air density."""
    return w.drag_area_m2 * (w.speed_mps + GUST_SIGMAS * w.gust_std_mps) ** 2


MAX_WIND_STRENGTH_M4PS2 = sc.MAX_DRAG_AREA_M2 * (sc.MAX_WIND_MPS
                                                 + GUST_SIGMAS * sc.MAX_GUST_STD_MPS) ** 2
"""The strongest one wind allowed: the bound on all the winds of a scenario together."""


def _peak_n(table: list[list[float]]) -> float:
    """The largest force of a grid's table, either way [N]."""
    return max((abs(f) for row in table for f in row), default=0.0)


def totals(scenario: sc.Scenario) -> list[tuple[str, float, float, str]]:
    """(field, total, bound, unit) of each summed quantity of ``scenario``'s disturbances."""
    ds = scenario.disturbances
    cur = [d for d in ds if isinstance(d, sc.Current)]
    body = [d for d in ds if isinstance(d, sc.BodyConstant)]
    world = [d for d in ds if isinstance(d, sc.WorldConstant)]
    grids = [d for d in ds if isinstance(d, sc.WorldGrid)]
    winds = [d for d in ds if isinstance(d, sc.Wind)]
    world_n = sum(abs(d.north_n) for d in world) + sum(_peak_n(g.north_n) for g in grids)
    world_e = sum(abs(d.east_n) for d in world) + sum(_peak_n(g.east_n) for g in grids)
    return [
        ("current north_mps", sum(abs(d.north_mps) for d in cur), sc.MAX_CURRENT_MPS, "m/s"),
        ("current east_mps", sum(abs(d.east_mps) for d in cur), sc.MAX_CURRENT_MPS, "m/s"),
        ("body_constant surge_n", sum(abs(d.surge_n) for d in body), sc.MAX_FORCE_N, "N"),
        ("body_constant sway_n", sum(abs(d.sway_n) for d in body), sc.MAX_FORCE_N, "N"),
        ("body_constant yaw_nm", sum(abs(d.yaw_nm) for d in body), sc.MAX_MOMENT_NM, "N m"),
        ("world_constant and world_grid north_n", world_n, sc.MAX_FORCE_N, "N"),
        ("world_constant and world_grid east_n", world_e, sc.MAX_FORCE_N, "N"),
        ("wind drag_area_m2 * (speed_mps + 3 gust_std_mps)^2",
         sum(_wind_strength_m4ps2(w) for w in winds), MAX_WIND_STRENGTH_M4PS2, "m^4/s^2"),
    ]


def check_world(scenario: sc.Scenario, where: str) -> None:
    """ConfigError naming ``where`` if ``scenario`` lists too many entries or its disturbances of
    one kind add up past what one of them may be (see the module docstring)."""
    problems = []
    if len(scenario.disturbances) > MAX_DISTURBANCES:
        problems.append(f"disturbances: {len(scenario.disturbances)} entries, at most "
                        f"{MAX_DISTURBANCES}")
    if len(scenario.faults) > MAX_FAULTS:
        problems.append(f"faults: {len(scenario.faults)} entries, at most {MAX_FAULTS}")
    for i, d in enumerate(scenario.disturbances):
        if isinstance(d, sc.WorldGrid) and len(d.xs_m) * len(d.ys_m) > MAX_GRID_POINTS:
            problems.append(f"disturbances.{i}: a world_grid of {len(d.xs_m)} x {len(d.ys_m)} "
                            f"points, at most {MAX_GRID_POINTS} in all")
    for field, total, bound, unit in totals(scenario):
        if total > bound:
            problems.append(f"disturbances: {field} adds up to {total:g} {unit} over the "
                            f"entries, at most {bound:g} {unit} (what one entry may be: "
                            "disturbances of one kind add)")
    if problems:
        raise ConfigError(f"{where}: scenario {scenario.name!r}: " + "; ".join(problems))
