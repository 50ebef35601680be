"""The researcher's worked example (``examples/controllers/pure_pursuit.py``): the page that walks
through it shows the file as it is, and the file registers a controller whose cost behaves as its
docstring says (zero on course at cruise; a heading error and a speed error both cost)."""

from __future__ import annotations

import math
import re

from seaway.vessel import model
from seaway.vessel.model import load_vessel
from seaway_controller import controllers, costs
from seaway_controller.ocp import OcpSpec

from tests.conftest import REPO

EXAMPLE = REPO / "examples" / "controllers" / "pure_pursuit.py"
PAGE = REPO / "docs" / "researcher" / "new-controller.md"


def test_the_page_shows_the_example_file_as_it_is():
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)
    assert blocks, f"{PAGE} has no python block"
    assert EXAMPLE.read_text() in blocks, (f"the python block of {PAGE} differs from {EXAMPLE}: "
                                           "paste the file into the page again")


def test_the_example_costs_nothing_on_course_at_cruise():
    (name,) = controllers.load_module(str(EXAMPLE))
    c = controllers.get(name)
    vessel, task_w = load_vessel("paper-boat"), 250.0
    spec = OcpSpec(name)
    u_star = costs.cruise_speed_mps(task_w, vessel)  # the economic cruise u* and its thrust T*
    t_star = model.sliding_resistance_n(u_star, vessel) / 2.0
    waypoint = (20.0, 0.0)  # due north of the vessel

    def cost(u, psi, thrust=(t_star, t_star)):
        return c.stage_cost([u, 0.0, 0.0, 0.0, 0.0, psi], thrust, waypoint, task_w, spec, vessel,
                            math)

    assert not c.economic
    assert math.isclose(cost(u_star, 0.0), 0.0, abs_tol=1e-12)
    assert cost(u_star, 0.3) > cost(u_star, 0.1) > 0.0  # heading away from P_i
    assert cost(0.5 * u_star, 0.0) > 0.0 and cost(1.5 * u_star, 0.0) > 0.0
    assert cost(u_star, 0.0, (t_star + 5.0, t_star - 5.0)) > 0.0
