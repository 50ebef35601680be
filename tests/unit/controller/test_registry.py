"""The controller registry: exactly the contract's names, and the OCP built only from the pieces."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from seaway.contract.messages import CONTROLLER_NAMES, MissionRequest, Waypoint
from seaway.vessel.model import load_vessel
from seaway_controller import controllers
from seaway_controller.controllers import Controller, check_names
from seaway_controller.ocp import CONTROLLER_KINDS, Ocp, OcpSpec

VP = load_vessel("paper-sim")
SRC = Path(controllers.__file__).resolve().parents[1]


def test_registered_names_are_the_contracts_in_its_order():
    assert tuple(controllers.CONTROLLERS) == CONTROLLER_NAMES == CONTROLLER_KINDS
    assert all(controllers.get(n).name == n for n in CONTROLLER_NAMES)


def test_a_registry_that_differs_from_the_contract_is_refused():
    check_names(["nmpc", "cc-empc", "eo-empc"], CONTROLLER_NAMES)  # order does not matter
    with pytest.raises(RuntimeError, match=r"not registered \['nmpc'\]"):
        check_names(["cc-empc", "eo-empc"], CONTROLLER_NAMES)
    with pytest.raises(RuntimeError, match=r"not in the contract \['lqr'\]"):
        check_names([*CONTROLLER_NAMES, "lqr"], CONTROLLER_NAMES)


def test_registering_a_name_twice_is_refused():
    twin = Controller("nmpc", controllers.get("nmpc").stage_cost, controllers.get("nmpc").guess_thrust)
    with pytest.raises(ValueError, match="registered twice"):
        controllers.register(twin)
    assert controllers.get("nmpc") is not twin


def test_unknown_controller_is_refused_naming_the_known_ones():
    with pytest.raises(ValueError, match="unknown controller 'lqr'; known: cc-empc, eo-empc, nmpc"):
        OcpSpec("lqr")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        MissionRequest.make(stamp_ns=0, waypoints=[Waypoint(x_m=0, y_m=0), Waypoint(x_m=1, y_m=0)],
                            coa_radius_m=1, task_power_w=0.49, controller="lqr")


def test_economic_controllers_have_times_and_the_terminal_constraint():
    for name in CONTROLLER_NAMES:
        ocp = Ocp(OcpSpec(name, horizon=2), VP)
        economic = controllers.get(name).economic
        assert ocp.spec.is_empc == economic
        assert ocp.nw == 2 * 8 + (2 if economic else 0)
        assert ocp.ng == 2 * 6 + (1 if economic else 0)
    assert [controllers.get(n).economic for n in CONTROLLER_NAMES] == [True, True, False]


def test_cc_and_eo_differ_only_in_the_gated_track_cost():
    """The gate is a parameter of both NLPs; only CC-EMPC's objective depends on it."""
    cc, eo = Ocp(OcpSpec("cc-empc", horizon=3), VP), Ocp(OcpSpec("eo-empc", horizon=3), VP)
    x0 = np.array([0.04, 0.0, 0.0, 1.0, 0.6, 0.1])
    on = cc.parameters(x0, (0.0, 0.0), (8.0, 0.0), True, 0.49)
    off = cc.parameters(x0, (0.0, 0.0), (8.0, 0.0), False, 0.49)
    w = cc.cold_guess(on)
    assert float(cc.objective_fn(w, on)) > float(cc.objective_fn(w, off))
    assert float(eo.objective_fn(w, on)) == float(eo.objective_fn(w, off)) == float(cc.objective_fn(w, off))


def test_no_module_branches_on_a_controller_name():
    """The OCP and the MPC dispatch through the registry: no ``kind == "nmpc"`` left anywhere."""
    for py in SRC.rglob("*.py"):
        tree = ast.parse(py.read_text(), str(py))
        for node in ast.walk(tree):
            if isinstance(node, ast.Compare):
                operands = [node.left, *node.comparators]
                named = [o.value for o in operands if isinstance(o, ast.Constant)
                         and o.value in CONTROLLER_NAMES]
                assert not named, f"{py.name}:{node.lineno} compares with {named}"
