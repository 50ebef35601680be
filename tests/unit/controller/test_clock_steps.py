"""A wall clock stepped under a flying controller (NTP or GPS time setting a Raspberry Pi's clock):
the energy counted takes its intervals from the monotonic clock, not from the wall clock's step.

Before: an hour forward counted an hour of the last command's power (about 900 kJ in the sim
profile), the battery read empty and the energy budget turned the vessel home."""

from __future__ import annotations

import pytest
from seaway.contract.messages import BatteryState

from tests.unit.controller.test_autopilot_truth import PACK
from tests.unit.controller.test_core import DT_NS, ScriptedSolver, make_core, mission, state

WALL0_NS = 1_800_000_000 * 10**9  # a wall clock [ns since the Unix epoch]
MONO0_NS = 5_000 * 10**9  # the monotonic clock then [ns]
HOUR_NS = 3600 * 10**9


def report(stamp_ns: int) -> BatteryState:
    return BatteryState(stamp_ns=stamp_ns, source="autopilot", voltage_v=12.6, remaining_frac=0.9,
                        remaining_j=0.9 * PACK.energy_j, capacity_j=PACK.energy_j)


def fly(core, k0: int, k1: int, wall_offset_ns: int = 0) -> None:
    """Control periods k0..k1-1, the wall clock ``wall_offset_ns`` off the monotonic one."""
    for k in range(k0, k1):
        wall = WALL0_NS + wall_offset_ns + k * DT_NS
        core.step(wall, state(k).model_copy(update={"stamp_ns": wall - 7}), MONO0_NS + k * DT_NS)


def flying_core():
    core = make_core(ScriptedSolver())
    assert core.handle_mission(WALL0_NS, mission()).accepted
    fly(core, 1, 5)
    assert core.missions.state == "active" and core.energy_used_j > 0
    return core


@pytest.mark.parametrize("step_ns", [HOUR_NS, -HOUR_NS, 10 * 365 * 24 * HOUR_NS])
def test_a_wall_clock_step_counts_one_period_of_energy(step_ns: int) -> None:
    core, ref = flying_core(), flying_core()
    fly(core, 5, 6, wall_offset_ns=step_ns)  # the step falls between periods 4 and 5
    fly(ref, 5, 6)
    assert core.energy_used_j == pytest.approx(ref.energy_used_j)
    assert core.energy_counted_j == pytest.approx(ref.energy_counted_j)
    assert core.missions.state == "active"


@pytest.mark.parametrize("step_ns", [HOUR_NS, -HOUR_NS])
def test_a_battery_report_from_across_a_step_counts_nothing_for_the_step(step_ns: int) -> None:
    core = flying_core()
    # The report is stamped an hour off the last step: the wall clock stepped in between. Stepped
    # back, its time since the last step was counted back: an hour's power off the count at the
    # report, an hour's power drawn from the battery at the next step.
    core.on_battery(report(WALL0_NS + 4 * DT_NS + step_ns))
    fly(core, 5, 6, wall_offset_ns=step_ns)
    left = core.battery_remaining_j()
    assert left is not None and left == pytest.approx(0.9 * PACK.energy_j, abs=100.0)


def test_lockstep_without_a_monotonic_clock_counts_on_its_own_time() -> None:
    core = make_core(ScriptedSolver())
    assert core.handle_mission(0, mission()).accepted
    core.step(DT_NS, state(1))
    before = core.energy_counted_j
    core.step(2 * DT_NS, state(2))
    assert core.energy_counted_j - before == pytest.approx(core._power_w() * 0.1)
