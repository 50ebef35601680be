"""The controller registry: exactly the contract's names shipped, controllers of one's own loaded from
a file or module (``load_module``), and the OCP built only from the pieces."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import numpy as np
import pytest
from seaway.contract.messages import CONTROLLER_NAMES, MissionRequest, Waypoint
from seaway.vessel.model import load_vessel
from seaway_controller import controllers
from seaway_controller.controllers import Controller, check_names
from seaway_controller.mission import MissionError, validate_mission
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


def _request(controller: str) -> MissionRequest:
    return MissionRequest.make(stamp_ns=0, waypoints=[Waypoint(x_m=0, y_m=0), Waypoint(x_m=9, y_m=0)],
                               coa_radius_m=1, task_power_w=0.49, controller=controller)


def test_unknown_controller_is_refused_naming_the_known_ones():
    with pytest.raises(ValueError, match="unknown controller 'lqr'; known: cc-empc, eo-empc, nmpc"):
        OcpSpec("lqr")  # type: ignore[arg-type]
    # The wire takes any well-spelled name (a controller module may register it); the controller
    # refuses one it has not registered, naming those it has.
    with pytest.raises(MissionError, match="unknown controller 'lqr'; known: cc-empc, eo-empc, nmpc"):
        validate_mission(_request("lqr"), None)
    for bad in ("LQR", "lqr!", "-lqr", "x" * 33, ""):
        with pytest.raises(ValueError, match="controller"):
            _request(bad)


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


PLUGIN = """
from seaway_controller.controllers import Controller, register, get

nmpc = get("nmpc")
register(Controller({name!r}, nmpc.stage_cost, nmpc.guess_thrust))
"""


def test_a_controller_module_registers_its_controller_once(tmp_path):
    f = tmp_path / "mine.py"
    f.write_text(PLUGIN.format(name="mine-a"))
    assert controllers.load_module(str(f)) == ("mine-a",)
    assert controllers.load_module(str(f)) == ("mine-a",)  # the same file again: nothing new
    assert controllers.get("mine-a").name == "mine-a" and "mine-a" in controllers.names()
    assert tuple(controllers.CONTROLLERS) == CONTROLLER_NAMES  # the shipped set is unchanged
    assert validate_mission(_request("mine-a"), None).controller == "mine-a"
    assert Ocp(OcpSpec("mine-a", horizon=2), VP).nw == 2 * 8


@pytest.mark.parametrize(("text", "problem"), [
    (None, "no such file"),
    ("x = 1\n", "registered no controller: it must call seaway_controller.controllers.register"),
    ("def broken(:\n", "SyntaxError"),
    (PLUGIN.format(name="nmpc"), "ValueError: controller 'nmpc' is registered twice"),
    (PLUGIN.format(name="Mine B"), "controller name 'Mine B': lower case letters, digits and '-'"),
])
def test_a_bad_controller_module_is_refused_saying_what_is_wrong(tmp_path, text, problem):
    f = tmp_path / "bad.py"
    if text is not None:
        f.write_text(text)
    with pytest.raises(controllers.ControllerModuleError, match=re.escape(problem)) as err:
        controllers.load_module(str(f))
    assert str(f) in str(err.value)
    assert tuple(controllers.CONTROLLERS) == CONTROLLER_NAMES


def test_a_module_name_that_cannot_be_imported_is_refused():
    with pytest.raises(controllers.ControllerModuleError, match=re.escape(
            "no_such_package.mine: ModuleNotFoundError")):
        controllers.load_module("no_such_package.mine")


def test_the_solver_of_a_controller_module_is_named_by_its_file(tmp_path):
    """Editing the module's file makes another solver (the cache key covers its code)."""
    from seaway_controller.ocp import spec_digest

    f = tmp_path / "mine_c.py"
    f.write_text(PLUGIN.format(name="mine-c"))
    controllers.load_module(str(f))
    first = spec_digest(OcpSpec("mine-c"), VP)
    f.write_text(PLUGIN.format(name="mine-c") + "# edited\n")
    assert spec_digest(OcpSpec("mine-c"), VP) != first
