"""``seaway bench hotpath`` splits each period of the in-process loop into its parts (issue 58, the
hot path): every period is counted once, the parts are the cores' own calls, and the cores are
left as they were. Pure: a few seconds of paper condition #1 in process."""

from __future__ import annotations

from seaway.simkit.scenario import load_scenario
from seaway_controller.core_energy import EnergyAccount
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore
from seaway_lab.bench import hotpath
from seaway_lab.closed_loop import run_closed_loop
from seaway_sim.core import SimCore


def test_each_period_is_split_into_the_parts_and_the_cores_are_restored() -> None:
    before = {(cls, name): cls.__dict__[name] for methods in hotpath.PARTS.values()
              for cls, name in methods}
    sc = load_scenario(hotpath.SCENARIO)
    cfg = EstimatorConfig().model_copy(update={"vessel": sc.vessel, "apply_dead_zone": sc.dead_zone})
    with hotpath.metered() as meter:
        r = run_closed_loop(sc, hotpath.CONTROLLER, estimator=EstimatorCore(cfg), battery=True,
                            max_time_s=3.0)
    # A period runs from one step of the sim to the next: one less than the steps taken.
    assert len(meter.periods) == r.steps - 1
    parts = hotpath.split(meter.periods)
    for part in ("estimator", "simulator", hotpath.MPC):
        assert all(ms > 0 for ms in parts[part]), part
    assert sum(parts["energy budget"]) > 0  # priced at the start and once a second
    for k in range(len(meter.periods)):
        assert parts[hotpath.REST][k] >= 0
        assert abs(sum(parts[p][k] for p in [*hotpath.PARTS, hotpath.REST])
                   - parts["period"][k]) < 1e-9
    assert {(cls, name): cls.__dict__[name] for (cls, name) in before} == before
    assert SimCore.advance is before[(SimCore, "advance")]
    assert EnergyAccount._update_budget is before[(EnergyAccount, "_update_budget")]
