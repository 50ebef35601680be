"""seaway.area: the geometry, the operating area's validation, and the checks of points, paths and
predicted trajectories against it."""

from __future__ import annotations

import json
import math

import pytest
from seaway.area import geometry as g
from seaway.area.model import (
    MAX_VERTICES,
    AreaError,
    OperatingArea,
    check_path,
    check_point,
    check_trajectory,
    margin_m,
)

SQUARE = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)]
# A U-shaped (non-convex) polygon: the notch (3..7 north, 4..6 east) is outside it.
U = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0), (0.0, 6.0), (7.0, 6.0), (7.0, 4.0), (0.0, 4.0)]


def lake(**more) -> OperatingArea:
    """A 40 m x 30 m keep-in, a rock (circle) and a pier (polygon) inside it, a rally point."""
    return OperatingArea.make(
        keep_in={"vertices_m": [(-5, -5), (35, -5), (35, 25), (-5, 25)]},
        keep_out_circles=[{"center_m": (15, 10), "radius_m": 2, "name": "rock"}],
        keep_out_polygons=[{"vertices_m": [(25, 20), (30, 20), (30, 25), (25, 25)], "name": "pier"}],
        rally_points=[{"position_m": (0, 0), "name": "jetty"}],
        **more,
    )


# -- geometry ------------------------------------------------------------------------------------


def test_point_in_polygon_counts_the_boundary_and_handles_a_notch() -> None:
    assert g.point_in_polygon((5, 5), SQUARE)
    assert g.point_in_polygon((0, 5), SQUARE) and g.point_in_polygon((10, 10), SQUARE)
    assert not g.point_in_polygon((10.001, 5), SQUARE)
    assert g.point_in_polygon((1, 1), U) and g.point_in_polygon((8, 5), U)
    assert not g.point_in_polygon((3, 5), U)  # in the notch


def test_segment_leaving_a_non_convex_polygon_is_found_though_both_ends_are_inside() -> None:
    # Both ends inside the U, the straight line between them crosses the notch.
    t = g.segment_leaves_polygon((1.0, 2.0), (1.0, 8.0), U)
    assert t is not None and 0.2 < t < 0.5
    assert g.segment_leaves_polygon((8.0, 2.0), (8.0, 8.0), U) is None  # round the notch's end
    assert g.segment_leaves_polygon((0.0, 0.0), (10.0, 0.0), SQUARE) is None  # along an edge
    assert g.segment_leaves_polygon((12.0, 0.0), (5.0, 5.0), SQUARE) == 0.0  # starts outside


def test_segments_touching_the_boundary() -> None:
    assert g.segment_leaves_polygon((10.0, 5.0), (15.0, 5.0), SQUARE) == 0.0  # from the edge, out
    assert g.segment_leaves_polygon((10.0, 5.0), (5.0, 5.0), SQUARE) is None  # from the edge, in
    assert g.segment_leaves_polygon((0.0, 5.0), (0.0, 15.0), SQUARE) == pytest.approx(0.5)  # along, out
    assert g.segment_enters_polygon((10.0, 15.0), (10.0, 10.0), SQUARE) == pytest.approx(1.0)  # to a corner
    assert g.segment_enters_polygon((-1.0, -1.0), (-1.0, 20.0), SQUARE) is None  # along, 1 m clear


def test_segment_entering_a_polygon_or_a_circle() -> None:
    assert g.segment_enters_polygon((-5, 5), (15, 5), SQUARE) == pytest.approx(0.25)
    assert g.segment_enters_polygon((-5, 15), (15, 15), SQUARE) is None
    assert g.segment_enters_polygon((-5, -5), (0, 0), SQUARE) == pytest.approx(1.0)  # touches
    assert g.segment_enters_circle((0, -10), (0, 10), (0, 0), 5) == pytest.approx(0.25)
    assert g.segment_enters_circle((6, -10), (6, 10), (0, 0), 5) is None
    assert g.segment_enters_circle((1, 1), (9, 9), (0, 0), 5) == 0.0  # starts inside


def test_self_intersection_names_the_edges() -> None:
    assert g.self_intersection(SQUARE) is None and g.self_intersection(U) is None
    bow_tie = [(0, 0), (10, 10), (10, 0), (0, 10)]
    assert g.self_intersection(bow_tie) == (0, 2)
    folded = [(0, 0), (10, 0), (5, 0), (5, 5)]  # edge 1 runs back along edge 0
    assert g.self_intersection(folded) is not None


def test_distance_to_the_boundary() -> None:
    assert g.distance_to_polygon_boundary_m((5, 3), SQUARE) == pytest.approx(3.0)
    assert g.distance_to_polygon_boundary_m((13, 14), SQUARE) == pytest.approx(5.0)


# -- validation ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("fields", "named"),
    [
        ({"keep_in": {"vertices_m": [(0, 0), (10, 10), (10, 0), (0, 10)]}}, "cross"),
        ({"keep_in": {"vertices_m": [(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]}}, "repeats vertex"),
        ({"keep_in": {"vertices_m": [(0, 0), (10, 0), (10, 0), (0, 10)]}}, "repeats vertex"),
        ({"keep_in": {"vertices_m": [(0, 0), (5, 5), (10, 10)]}}, "one line"),
        ({"keep_in": {"vertices_m": [(0, 0), (10, 0)]}}, "at least 3"),
        ({"keep_in": {"vertices_m": [(0, 0), (0.5, 0), (0, 0.5)]}}, "m^2"),
        (
            {
                "keep_in": {
                    "vertices_m": [
                        (float(math.cos(k / 20)), float(math.sin(k / 20))) for k in range(MAX_VERTICES + 1)
                    ]
                }
            },
            f"at most {MAX_VERTICES}",
        ),
        ({"keep_in": {"vertices_m": [(0, 0), (math.nan, 0), (0, 10)]}}, "finite"),
        ({"keep_in": {"vertices_m": [(0, 0), (2e5, 0), (0, 10)]}}, "vertices_m[1]"),
        ({"keep_out_circles": [{"center_m": (0, 0), "radius_m": 0}]}, "greater than 0"),
        ({"keep_out_circles": [{"center_m": (0, 0), "radius_m": -1}]}, "radius_m"),
        ({"keep_in": {"vertices_m": SQUARE}, "rally_points": [{"position_m": (20, 20)}]}, "rally_points[0]"),
        (
            {
                "keep_out_circles": [{"center_m": (0, 0), "radius_m": 5}],
                "rally_points": [{"position_m": (1, 1)}],
            },
            "keep_out_circles[0]",
        ),
        ({"keep_in": {"vertices_m": SQUARE, "colour": "red"}}, "unknown field"),
    ],
)
def test_bad_areas_are_refused_naming_the_field(fields: dict, named: str) -> None:
    with pytest.raises(AreaError) as err:
        OperatingArea.make(**fields)
    assert named in str(err.value)


def test_home_outside_the_area_is_refused_naming_it() -> None:
    area = lake()
    area.require_inside((0.0, 0.0), "home")
    with pytest.raises(AreaError, match=r"home at north 50\.0 m.*outside the keep-in"):
        area.require_inside((50.0, 0.0), "home")
    with pytest.raises(AreaError, match="rock"):
        area.require_inside((15.0, 10.0), "home")


# -- checks --------------------------------------------------------------------------------------


def test_a_path_inside_passes() -> None:
    verdict = check_path(lake(), [(0, 0), (30, 0), (30, 15), (0, 15)], position_m=(1, 1))
    assert verdict.ok and verdict.reason == "" and verdict.first is None


def test_the_way_to_the_first_waypoint_is_leg_zero() -> None:
    # The mission is inside, but the vessel is across the rock from P_0.
    verdict = check_path(lake(), [(20, 10), (30, 10)], position_m=(10, 10))
    assert not verdict.ok
    assert verdict.first.leg == 0 and verdict.first.kind == "enters_keep_out"
    assert "rock" in verdict.first.zone and "leg 0" in verdict.reason
    assert verdict.first.at_m[0] == pytest.approx(13.0)


def test_a_leg_leaving_the_keep_in_area_is_named() -> None:
    verdict = check_path(lake(), [(0, 0), (20, 0), (20, 40)], position_m=(0, 0))
    assert [(b.leg, b.kind, b.zone) for b in verdict.breaches] == [(2, "leaves_keep_in", "keep_in")]
    assert verdict.first.at_m == pytest.approx((20.0, 25.0))


def test_a_leg_through_the_pier_and_out_lists_both_in_path_order() -> None:
    verdict = check_path(lake(), [(0, 0), (27, 0), (27, 30)])
    assert [(b.leg, b.kind) for b in verdict.breaches] == [(2, "enters_keep_out"), (2, "leaves_keep_in")]
    assert "pier" in verdict.breaches[0].zone


def test_without_a_position_a_first_waypoint_outside_is_leg_zero() -> None:
    verdict = check_path(lake(), [(50, 0), (0, 0)])
    assert verdict.first.leg == 0 and verdict.first.kind == "leaves_keep_in"


def test_a_trajectory_check_names_the_first_step_outside() -> None:
    horizon = [(30.0, 0.0), (32.0, 0.0), (34.0, 0.0), (36.0, 0.0), (38.0, 0.0)]
    verdict = check_trajectory(lake(), horizon)
    assert len(verdict.breaches) == 1
    assert verdict.first.leg == 2 and verdict.first.at_m == pytest.approx((35.0, 0.0))
    assert "step 2" in verdict.reason
    assert check_trajectory(lake(), horizon[:3]).ok
    assert not check_trajectory(lake(), [(15.0, 10.0)]).ok  # one point, in the rock


def test_point_checks_and_signed_margin() -> None:
    area = lake()
    assert check_point(area, (0, 0)) is None
    assert check_point(area, (40, 0)).kind == "leaves_keep_in"
    assert margin_m(area, (0.0, 0.0)) == pytest.approx(5.0)  # 5 m to the keep-in's edge
    assert margin_m(area, (15.0, 13.0)) == pytest.approx(1.0)  # 1 m from the rock
    assert margin_m(area, (15.0, 11.0)) == pytest.approx(-1.0)  # 1 m into the rock
    assert margin_m(area, (37.0, 0.0)) == pytest.approx(-2.0)  # 2 m out of the keep-in
    assert margin_m(OperatingArea(), (0.0, 0.0)) == math.inf
    assert OperatingArea().empty and not area.empty


# -- on the bus ----------------------------------------------------------------------------------


def test_the_area_message_carries_the_area_exactly_and_refuses_an_invalid_one() -> None:
    from seaway.contract.messages import ActiveArea, MessageError

    msg = ActiveArea.of_area(lake(), stamp_ns=5, since_ns=3, source="lake")
    back = ActiveArea.decode(msg.encode())
    assert back == msg and back.to_area() == lake()
    wire = json.loads(msg.encode())
    wire["keep_in"]["vertices"] = [
        {"x_m": 0, "y_m": 0},
        {"x_m": 10, "y_m": 10},
        {"x_m": 10, "y_m": 0},
        {"x_m": 0, "y_m": 10},
    ]
    with pytest.raises(MessageError, match=r"ActiveArea.*cross"):
        ActiveArea.decode(json.dumps(wire))
