"""Mission files: QGroundControl .plan and GeoJSON read into WGS84 waypoints, written back, and
every refusal naming the item at fault (seaway.mission_files, seaway_groundstation.bodies)."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest
from seaway import mission_export
from seaway import mission_files as plans
from seaway.contract.messages import MISSION_OPTIONS, MissionRequest, Waypoint
from seaway.mission_files import PlanError
from seaway.vessel.frames import GeoOrigin
from seaway_groundstation import bodies

DATA = Path(__file__).parent / "data"


def load(name: str) -> dict:
    return json.loads((DATA / name).read_text())


# -- real QGroundControl plans ------------------------------------------------------------------


def test_real_plan_with_takeoff_is_refused_naming_the_item_unless_skipped() -> None:
    doc = load("simple_square.plan")
    with pytest.raises(PlanError, match=r"mission.items\[0\] \(doJumpId 1\): command 22 \(NAV_TAKEOFF\)"):
        plans.parse_plan(doc)
    path = plans.parse_plan(doc, skip_unsupported=True)
    assert path.points_deg == ((47.398742, 8.546594), (47.398742, 8.544594),
                               (47.396742, 8.544594), (47.396742, 8.546594))
    assert len(path.skipped) == 1 and "NAV_TAKEOFF" in path.skipped[0]
    assert path.hints == {}  # acceptance radius 0 in the file: no hint; cruiseSpeed is never one


def test_real_rover_plan_keeps_waypoints_in_global_frames_and_skips_the_rest() -> None:
    path = plans.parse_document(load("PX4SITL-ArduRover.plan"), skip_unsupported=True)
    assert path.source == "plan"
    assert path.points_deg == ((47.4104747, 8.565406), (47.397, 8.585312), (47.3700507, 8.5455),
                               (47.3700507, 8.505688), (47.397, 8.505688))
    names = " | ".join(path.skipped)
    assert "NAV_LOITER_TIME" in names and "NAV_RETURN_TO_LAUNCH" in names
    # Its DO_CHANGE_SPEED (5 m/s, after the second waypoint) is the speed of the waypoints after it,
    # and the first speed given is the mission's cruise hint.
    assert "DO_CHANGE_SPEED" not in names
    assert path.speeds_mps == (None, None, 5.0, 5.0, 5.0)
    assert path.hints["speed_hint_mps"] == 5.0


def test_speeds_are_read_from_geojson_and_bad_ones_refused_naming_them() -> None:
    line = {"type": "LineString", "coordinates": [[8.5, 47.3], [8.501, 47.3], [8.501, 47.301]]}
    path = plans.parse_geojson({"type": "Feature", "geometry": line,
                                "properties": {"speeds_mps": [1.2, None, 0.8]}})
    assert path.speeds_mps == (1.2, None, 0.8) and path.hints["speed_hint_mps"] == 1.2
    own = plans.parse_geojson({"type": "Feature", "geometry": line,
                               "properties": {"speeds_mps": [1.2, None, 0.8], "speed_hint_mps": 0.9}})
    assert own.hints["speed_hint_mps"] == 0.9  # the file's own hint wins
    for bad, match in (([1.0, 2.0], "list of 3 speeds"), ([1.0, -1.0, 1.0], r"speeds_mps\[1\]: speed -1"),
                       ([1.0, "fast", 1.0], r"speeds_mps\[1\]"), ([1.0, 1.0, 99.0], r"\(0, 50\]")):
        with pytest.raises(PlanError, match=match):
            plans.parse_geojson({"type": "Feature", "geometry": line, "properties": {"speeds_mps": bad}})
    plan = load("PX4SITL-ArduRover.plan")
    plan["mission"]["items"][2]["params"][1] = 0
    with pytest.raises(PlanError, match=r"items\[2\].*DO_CHANGE_SPEED.*speed 0"):
        plans.parse_plan(plan, skip_unsupported=True)


# The geoFence and rallyPoints as QGroundControl writes them (GeoFenceController, QGCFencePolygon,
# QGCFenceCircle, RallyPointController): around the real square plan's waypoints.
QGC_FENCE = {
    "circles": [{"circle": {"center": [47.3977, 8.5455], "radius": 20.0}, "inclusion": False,
                 "version": 1}],
    "polygons": [{"inclusion": True, "polygon": [[47.3995, 8.5435], [47.3995, 8.5475],
                                                 [47.3960, 8.5475], [47.3960, 8.5435]], "version": 1}],
    "version": 2,
}
QGC_RALLY = {"points": [[47.3980, 8.5460, 10.0], [47.3970, 8.5440, 10.0]], "version": 2}


def test_plan_geofence_and_rally_points_are_read_not_dropped() -> None:
    doc = {**load("simple_square.plan"), "geoFence": QGC_FENCE, "rallyPoints": QGC_RALLY}
    path = plans.parse_plan(doc, skip_unsupported=True)
    assert path.area is not None
    assert path.area.keep_in.vertices_deg[0] == (47.3995, 8.5435)
    assert path.area.keep_out[0].center_deg == (47.3977, 8.5455) and path.area.keep_out[0].radius_m == 20.0
    assert [r.position_deg for r in path.area.rally] == [(47.398, 8.546), (47.397, 8.544)]
    assert plans.parse_plan(load("simple_square.plan"), skip_unsupported=True).area is None  # empty


def test_plan_with_geofence_and_rally_points_round_trips_through_import_and_export() -> None:
    doc = {**load("simple_square.plan"), "geoFence": QGC_FENCE, "rallyPoints": QGC_RALLY}
    path = plans.parse_plan(doc, skip_unsupported=True)
    out = json.loads(json.dumps(mission_export.to_plan(path.points_deg, coa_radius_m=2.0, area=path.area)))
    assert out["geoFence"] == QGC_FENCE
    assert out["rallyPoints"]["points"] == [[47.398, 8.546, 0.0], [47.397, 8.544, 0.0]]  # at the surface
    again = plans.parse_plan(out)
    assert again.area == path.area and again.points_deg == path.points_deg


def test_geojson_export_carries_the_area_and_reads_it_back() -> None:
    path = plans.parse_plan({**load("simple_square.plan"), "geoFence": QGC_FENCE,
                             "rallyPoints": QGC_RALLY}, skip_unsupported=True)
    doc = json.loads(json.dumps(mission_export.to_geojson(path.points_deg, {"coa_radius_m": 2.0},
                                                          area=path.area)))
    assert doc["type"] == "FeatureCollection"
    again = plans.parse_geojson(doc)
    assert again.area == path.area and again.points_deg == path.points_deg
    assert again.hints == {"coa_radius_m": 2.0}


def test_a_bad_plan_fence_is_refused_as_a_plan_error_naming_it() -> None:
    fence = copy.deepcopy(QGC_FENCE)
    fence["circles"][0]["inclusion"] = True
    with pytest.raises(PlanError, match=r"geoFence.circles\[0\]: an inclusion circle"):
        plans.parse_plan({**load("simple_square.plan"), "geoFence": fence}, skip_unsupported=True)


def test_plan_round_trip_keeps_points_and_acceptance_radius() -> None:
    points = [(47.3977, 8.5456), (47.3987, 8.5466), (47.3987, 8.5446)]
    doc = mission_export.to_plan(points, coa_radius_m=2.5, cruise_speed_mps=1.2)
    assert doc["fileType"] == "Plan" and doc["mission"]["version"] == 2
    assert all(item["command"] == 16 and item["type"] == "SimpleItem" for item in doc["mission"]["items"])
    back = plans.parse_plan(json.loads(json.dumps(doc)))
    assert back.points_deg == tuple(points)
    assert back.hints == {"coa_radius_m": 2.5}


# -- plan refusals ------------------------------------------------------------------------------


def _square() -> dict:
    return mission_export.to_plan([(47.0, 8.0), (47.001, 8.0), (47.001, 8.001)])


@pytest.mark.parametrize("mutate, match", [
    (lambda d: d.update(fileType="Mission"), r"fileType is \"Mission\", not \"Plan\""),
    (lambda d: d.pop("mission"), "no mission object"),
    (lambda d: d["mission"].update(version=1), "mission version 1 is not supported"),
    (lambda d: d["mission"].update(items={}), "mission.items must be a list"),
    (lambda d: d["mission"]["items"][1].update(type="ComplexItem", complexItemType="survey"),
     r"items\[1\] \(doJumpId 2\): a ComplexItem \(survey\) is not supported"),
    (lambda d: d["mission"]["items"][1].update(type="Other"),
     r"items\[1\].*not a QGroundControl mission item"),
    (lambda d: d["mission"]["items"][2].update(frame=1), r"items\[2\].*frame 1 has no latitude/longitude"),
    (lambda d: d["mission"]["items"][0].update(params=[0, 0, 0]), r"items\[0\].*params must be a list of 7"),
    (lambda d: d["mission"]["items"][0]["params"].__setitem__(4, 95.0), r"items\[0\].*latitude 95.0"),
    (lambda d: d["mission"]["items"][0]["params"].__setitem__(5, "8"),
     r"items\[0\].*longitude: expected a finite"),
    (lambda d: d["mission"]["items"][0].update(command="16"),
     r"items\[0\].*not a MAVLink command number"),
    (lambda d: d["mission"].update(items=d["mission"]["items"][:1]),
     "at least 2 waypoints, the file gives 1"),
])
def test_plan_refusals_name_the_problem(mutate, match) -> None:
    doc = copy.deepcopy(_square())
    mutate(doc)
    with pytest.raises(PlanError, match=match):
        plans.parse_document(doc)


def test_complex_item_can_be_skipped_and_too_many_waypoints_are_refused() -> None:
    doc = _square()
    doc["mission"]["items"].append({"type": "ComplexItem", "complexItemType": "CorridorScan"})
    assert len(plans.parse_plan(doc, skip_unsupported=True).skipped) == 1
    with pytest.raises(PlanError, match="more than the 2 allowed"):
        plans.parse_plan(_square(), max_waypoints=2)


def test_json_text_with_nan_or_bad_syntax_is_refused() -> None:
    with pytest.raises(PlanError, match="NaN is not a number JSON allows"):
        plans.load_json(b'{"a": NaN}')
    with pytest.raises(PlanError, match=r"not JSON: .* line 1"):
        plans.load_json(b'{"a": ')
    with pytest.raises(PlanError, match="not UTF-8"):
        plans.load_json(b'\xff\xfe')
    with pytest.raises(PlanError, match="neither a QGroundControl plan"):
        plans.parse_document([1, 2])


# -- GeoJSON --------------------------------------------------------------------------------------


def test_rfc7946_example_needs_skip_for_its_point_and_polygon() -> None:
    doc = load("rfc7946-example.geojson")
    with pytest.raises(PlanError, match=r"features\[0\]: geometry type \"Point\" is not a LineString"):
        plans.parse_document(doc)
    path = plans.parse_document(doc, skip_unsupported=True)
    assert path.source == "geojson"
    # longitude first in GeoJSON, (lat, lon) here
    assert path.points_deg == ((0.0, 102.0), (1.0, 103.0), (0.0, 104.0), (1.0, 105.0))
    assert len(path.skipped) == 2


@pytest.mark.parametrize("wrap", ["bare", "feature", "collection"])
def test_geojson_line_in_each_form(wrap: str) -> None:
    line = {"type": "LineString", "coordinates": [[8.5, 47.3], [8.51, 47.31, 400.0]]}
    doc = {"bare": line, "feature": {"type": "Feature", "geometry": line, "properties": None},
           "collection": {"type": "FeatureCollection",
                          "features": [{"type": "Feature", "geometry": line, "properties": {}}]}}[wrap]
    assert plans.parse_geojson(doc).points_deg == ((47.3, 8.5), (47.31, 8.51))


@pytest.mark.parametrize("doc, match", [
    ({"type": "MultiLineString", "coordinates": []}, "type \"MultiLineString\" is not supported"),
    ({"type": "Feature", "geometry": {"type": "Point", "coordinates": [1, 2]}}, "not a LineString"),
    ({"type": "FeatureCollection", "features": []}, "holds 0 LineString features"),
    ({"type": "FeatureCollection", "features": [
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": [[0, 0], [1, 1]]}},
        {"type": "Feature", "geometry": {"type": "LineString", "coordinates": [[0, 0], [1, 1]]}}]},
     r"holds 2 LineString features \(at features\[0\], features\[1\]\)"),
    ({"type": "LineString", "coordinates": [[8.5], [8.6, 47.0]]}, r"coordinates\[0\] must be \[lon, lat\]"),
    ({"type": "LineString", "coordinates": [[8.5, 91.0], [8.6, 47.0]]}, r"coordinates\[0\]: latitude 91.0"),
    ({"type": "LineString", "coordinates": [[8.5, 47.0]]}, "at least 2 waypoints"),
    ({"type": "LineString", "coordinates": [[8.5, 47.0], [8.6, 47.0]],
      "crs": {"type": "name", "properties": {"name": "EPSG:3857"}}}, "is not WGS84"),
])
def test_geojson_refusals(doc, match) -> None:
    with pytest.raises(PlanError, match=match):
        plans.parse_document(doc)


def test_geojson_export_round_trip_carries_mission_parameters() -> None:
    # Every option away from its default, so that one the export or the import forgot shows.
    req = MissionRequest.make(stamp_ns=1, mission_id="m1", coa_radius_m=3.0, task_power_w=20.0,
                              controller="eo-empc", predict_disturbance=True, speed_hint_mps=1.2,
                              on_low_energy="hold", join_first_leg=True, at_rest="drift",
                              on_area_breach="return",
                              waypoints=[Waypoint(lat_deg=47.0, lon_deg=8.0),
                                         Waypoint(lat_deg=47.001, lon_deg=8.001)])
    assert set(plans.FILE_OPTIONS) | {"force"} == set(MISSION_OPTIONS)
    doc = mission_export.to_geojson(bodies.mission_points_deg(req.waypoints, None),
                                    bodies.mission_properties(req))
    assert doc["geometry"]["coordinates"] == [[8.0, 47.0], [8.001, 47.001]]
    path = plans.parse_document(json.loads(json.dumps(doc)))
    again = bodies.mission_from_import(path, bodies.ImportParams(), 2)
    assert again.model_dump(exclude={"stamp_ns"}) == req.model_dump(exclude={"stamp_ns"})
    # force is the operator's choice when sending: an exported file never carries it
    forced = req.model_copy(update={"force": True})
    assert "force" not in bodies.mission_properties(forced)
    # a policy property of the wrong JSON type is refused by name, not turned into a value
    bad = json.loads(json.dumps(doc))
    bad["properties"]["join_first_leg"] = "yes"
    with pytest.raises(PlanError, match="join_first_leg"):
        plans.parse_document(bad)
    # the request's own values beat the file's
    faster = bodies.mission_from_import(path, bodies.ImportParams(task_power_w=5.0, controller="nmpc"), 3)
    assert (faster.task_power_w, faster.controller, faster.coa_radius_m) == (5.0, "nmpc", 3.0)


# -- mission building and export through the origin --------------------------------------------


def test_import_without_radius_or_power_is_refused_and_bad_hints_name_the_field() -> None:
    path = plans.parse_plan(_square())
    with pytest.raises(bodies.MissionBuildError, match="coa_radius_m is required: the plan file"):
        bodies.mission_from_import(path, bodies.ImportParams(task_power_w=1.0), 1)
    bad = plans.ImportedPath("geojson", path.points_deg, hints={"controller": "PID!", "coa_radius_m": 1,
                                                                "task_power_w": 0.49})
    with pytest.raises(bodies.MissionBuildError, match=r"MissionRequest\.controller"):
        bodies.mission_from_import(bad, bodies.ImportParams(), 1)


def test_metre_waypoints_export_through_the_origin_and_refuse_without_one() -> None:
    origin = GeoOrigin.from_degrees(47.0, 8.0)
    wps = [Waypoint(x_m=0.0, y_m=0.0), Waypoint(x_m=111.2, y_m=0.0)]
    (lat0, lon0), (lat1, lon1) = bodies.mission_points_deg(wps, origin)
    assert math.isclose(lat0, 47.0, abs_tol=1e-9) and math.isclose(lon0, 8.0, abs_tol=1e-9)
    assert math.isclose(lat1 - 47.0, 0.001, rel_tol=0.01) and math.isclose(lon1, 8.0, abs_tol=1e-9)
    with pytest.raises(bodies.ExportError, match="waypoint 0 is in local metres and no NED origin"):
        bodies.mission_points_deg(wps, None)
