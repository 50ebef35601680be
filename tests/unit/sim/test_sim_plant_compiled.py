"""The plant's compiled substeps (``seaway.simkit.compiled``) give the same floats as its Python
steps: the paper's table is reproduced to the digit whichever path the plant takes (issue 58, the
hot path). Pure: two plants of one scenario, one made to step in Python."""

from __future__ import annotations

import random

import pytest
from seaway.simkit.plant import Plant
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel

pytest.importorskip("casadi")


def pair(scenario: str, vessel: str | None = None) -> tuple[Plant, Plant]:
    sc = load_scenario(scenario)
    vp = load_vessel(vessel or sc.plant_vessel_file)
    compiled, python = Plant(sc, vp), Plant(sc, vp)
    python.substeps = None
    return compiled, python


@pytest.mark.parametrize(("scenario", "vessel"), [
    ("paper-c1", None),  # no disturbance
    ("paper-c2", None),  # a body-frame force
    ("paper-c4", None),  # a world-frame force, rotated at each RK4 stage
    ("lake", None),  # wind with seeded gusts: a disturbance drawn at every substep
    ("paper-c1", "px4-sitl-rover"),  # a vessel with surge friction (tanh, exp)
])
def test_compiled_substeps_are_the_python_steps_bit_for_bit(scenario, vessel) -> None:
    compiled, python = pair(scenario, vessel)
    if compiled.substeps is None:
        pytest.skip("no C compiler: the plant steps in Python only")
    rng = random.Random(7)
    for i in range(1500):
        # Steps of one to twenty substeps (two compiled calls), and one shorter than a substep.
        cmd = (rng.uniform(-3.0, 6.0), rng.uniform(-3.0, 6.0))
        dt = rng.choice([0.05, 0.1, 0.2, 0.013, 0.003])
        a, b = compiled.step(cmd, dt), python.step(cmd, dt)
        assert (a.x, a.energy_j, a.t_s, a.thrust_n, a.last_disturbance_body, a.last_current_ne) == (
            b.x, b.energy_j, b.t_s, b.thrust_n, b.last_disturbance_body, b.last_current_ne), i


@pytest.mark.parametrize("scenario", ["paper-c5", "lake-faults"])
def test_a_disturbance_field_or_a_fault_keeps_the_python_steps(scenario) -> None:
    """A disturbance that varies with position, a scheduled fault: the inputs of a substep are not
    known before the one before it, so the plant steps in Python."""
    sc = load_scenario(scenario)
    assert Plant(sc, load_vessel(sc.plant_vessel_file)).substeps is None
