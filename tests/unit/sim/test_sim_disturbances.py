"""The paper's five disturbance conditions as the sim reports and applies them (body frame, N).

Each expected value is worked out by hand from shared/reproduction.md: a world-frame force
(F_north, F_east) acts in the body frame as surge = F_n cos(psi) + F_e sin(psi),
sway = -F_n sin(psi) + F_e cos(psi) (R(psi)^T, psi clockwise from north).
"""

from __future__ import annotations

import json
import math

import pytest
from seaway.contract.config import ConfigError, deploy_path
from seaway.simkit.scenario import WorldGrid, bilinear, load_scenario, parse_scenario
from seaway.vessel.model import load_vessel
from seaway_sim.core import SimCore

S2 = math.sqrt(0.5)


def core_at(name: str, psi_rad: float, x_m: float = 0.0, y_m: float = 0.0) -> SimCore:
    """The sim's core for scenario ``name`` with the vessel started at the given pose."""
    sc = load_scenario(name)
    sc = sc.model_copy(update={"start": sc.start.model_copy(
        update={"psi_rad": psi_rad, "x_m": x_m, "y_m": y_m})})
    return SimCore(sc, load_vessel(sc.vessel))


def reported(core: SimCore) -> tuple[float, float, float]:
    d = core.disturbance()
    return d.surge_n, d.sway_n, d.yaw_nm


@pytest.mark.parametrize("psi", [0.0, math.pi / 2, -math.pi / 4, 2.0])
def test_condition_1_is_no_force_at_any_heading(psi: float) -> None:
    assert reported(core_at("paper-c1", psi)) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("psi", [0.0, math.pi / 2, -math.pi / 4])
def test_condition_2_is_body_fixed_whatever_the_heading(psi: float) -> None:
    assert reported(core_at("paper-c2", psi)) == pytest.approx((0.015, 0.015, 0.0), abs=1e-15)


# Condition #3: world force (north, east) = (-0.0003, 0.0799) N.
@pytest.mark.parametrize(("psi", "surge", "sway"), [
    (0.0, -0.0003, 0.0799),                                  # heading north: body = world
    (math.pi / 2, 0.0799, 0.0003),                           # heading east: east force is ahead
    (-math.pi / 4, S2 * (-0.0003) - S2 * 0.0799,             # heading north-west
     S2 * (-0.0003) + S2 * 0.0799),
])
def test_condition_3_world_force_rotated_into_body(psi: float, surge: float, sway: float) -> None:
    assert reported(core_at("paper-c3", psi)) == pytest.approx((surge, sway, 0.0), abs=1e-15)


@pytest.mark.parametrize(("psi", "surge", "sway"), [
    (0.0, -0.0987, 0.0868),
    (math.pi / 2, 0.0868, 0.0987),
    (math.pi, 0.0987, -0.0868),
])
def test_condition_4_world_force_rotated_into_body(psi: float, surge: float, sway: float) -> None:
    assert reported(core_at("paper-c4", psi)) == pytest.approx((surge, sway, 0.0), abs=1e-15)


def grid_file() -> dict:
    return json.loads(deploy_path("scenarios", "data", "condition5_grid.json").read_text())


def test_condition_5_grid_at_a_node_and_between_nodes_by_hand() -> None:
    g = grid_file()
    xs, ys, tx, ty = g["xs"], g["ys"], g["tx"], g["ty"]
    # At the node (xs[1], ys[1]) = (0, 0), heading north: the node's values exactly.
    assert reported(core_at("paper-c5", 0.0)) == pytest.approx((tx[1][1], ty[1][1], 0.0), abs=1e-15)
    # Midway between four nodes: their mean; heading east swaps the axes (surge = east force).
    x, y = (xs[2] + xs[3]) / 2, (ys[1] + ys[2]) / 2
    mean_n = (tx[2][1] + tx[3][1] + tx[2][2] + tx[3][2]) / 4
    mean_e = (ty[2][1] + ty[3][1] + ty[2][2] + ty[3][2]) / 4
    assert reported(core_at("paper-c5", math.pi / 2, x, y)) == pytest.approx(
        (mean_e, -mean_n, 0.0), abs=1e-12)


SMALL = WorldGrid(kind="world_grid", xs_m=[0.0, 10.0, 20.0], ys_m=[0.0, 4.0],
                  north_n=[[0.0, 4.0], [10.0, 14.0], [20.0, 40.0]],
                  east_n=[[1.0, 1.0], [1.0, 1.0], [-1.0, 3.0]])


@pytest.mark.parametrize(("x", "y", "north", "east"), [
    (0.0, 0.0, 0.0, 1.0),          # a corner node
    (5.0, 0.0, 5.0, 1.0),          # on an edge: linear in x
    (5.0, 2.0, 7.0, 1.0),          # cell centre: mean of 0, 10, 4, 14
    # (15, 1): cell x in [10, 20], y in [0, 4], so tx = 0.5, ty = 0.25 and the weights are
    # 0.375 (10, 0), 0.375 (20, 0), 0.125 (10, 4), 0.125 (20, 4):
    # north = 0.375*10 + 0.375*20 + 0.125*14 + 0.125*40 = 18; east = 0.375 - 0.375 + 0.125 + 0.375
    (15.0, 1.0, 18.0, 0.5),
    (-5.0, 2.0, 2.0, 1.0),         # clamped in x to the first column, bilinear in y
    (30.0, 9.0, 40.0, 3.0),        # clamped in both to the far corner
    (25.0, -3.0, 20.0, -1.0),      # clamped to the corner (20, 0)
])
def test_bilinear_by_hand_including_clamping(x: float, y: float, north: float, east: float) -> None:
    assert bilinear(SMALL, x, y) == pytest.approx((north, east), abs=1e-12)


def test_the_plant_feels_the_reported_force() -> None:
    """Condition #3 at rest, heading east: the east force pushes the vessel ahead.

    Starting at rest with psi = pi/2 and no thrust, the first moments follow u' = F_surge / m11 and
    v' = F_sway / m22 with the hand-rotated force, so the plant applies what the sim reports.
    """
    core = core_at("paper-c3", math.pi / 2)
    dt_ns = 10_000_000
    core.advance((0.0, 0.0), dt_ns)
    u, v = core.plant.state.x[0], core.plant.state.x[1]
    p = core.vessel
    # Over 10 ms the damping barely acts: u ~ F/m * dt (relative error ~ Xu dt / (2 m11) < 2 %).
    assert u == pytest.approx(0.0799 / p.m11_kg * 0.01, rel=0.02)
    assert v == pytest.approx(0.0003 / p.m22_kg * 0.01, rel=0.03)


@pytest.mark.parametrize(("entry", "named"), [
    ({"file": 5}, r"disturbances\.0\.file: 5 is not a file's path"),  # was a TypeError
    ({"file": "latin.json"}, r"disturbances\.0\.file: .*latin\.json: not UTF-8 text \(byte 0 is 0xff\)"),
    ({"file": "grid.json", "xs_m": [5.0, 6.0]},  # was silently replaced by the file's
     r"disturbances\.0: xs_m given beside file 'grid\.json'"),
    ({"file": "grid.json", "scale": [1]}, r"disturbances\.0\.scale: \[1\] is not a finite number"),
    ({"file": "deep.json"}, r"disturbances\.0\.file: .*deep\.json: not a usable document: nested"),
])
def test_a_bad_grid_file_entry_is_refused_naming_the_field(tmp_path, entry, named) -> None:
    (tmp_path / "grid.json").write_text(json.dumps({"xs": [0, 1], "ys": [0, 1], "tx": [[0, 0], [0, 0]],
                                                    "ty": [[0, 0], [0, 0]]}))
    (tmp_path / "latin.json").write_bytes(b"\xff\xfe{}")
    (tmp_path / "deep.json").write_text("[" * 3000 + "]" * 3000)
    doc = {"name": "g", "seed": 1, "vessel": "paper-boat",
           "disturbances": [{"kind": "world_grid", **entry}]}
    with pytest.raises(ConfigError, match=rf"^probe\.toml: {named}"):
        parse_scenario(doc, "probe.toml", tmp_path)
    grid = parse_scenario({**doc, "disturbances": [{"kind": "world_grid", "file": "grid.json", "scale": 2}]},
                          "probe.toml", tmp_path).disturbances[0]
    assert isinstance(grid, WorldGrid) and grid.xs_m == [0.0, 1.0]  # the file alone is read
