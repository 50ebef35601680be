"""seaway.area.spec, .plan, .geojson and .files: the operating area in TOML, QGroundControl .plan
(geoFence, rallyPoints) and GeoJSON, each round-tripped, and bad files refused naming what is wrong."""

from __future__ import annotations

import copy
import json
import math

import pytest
from seaway.area import files, geojson, plan
from seaway.area import spec as area_spec
from seaway.area.model import AreaError, OperatingArea
from seaway.vessel.frames import GeoOrigin

ORIGIN = GeoOrigin.from_degrees(28.18, 112.94, 30.0)


def area() -> OperatingArea:
    return OperatingArea.make(
        keep_in={"vertices_m": [(-10, -10), (35, -10), (35, 30), (-10, 30)], "name": "bay"},
        keep_out_polygons=[{"vertices_m": [(25, 20), (30, 20), (30, 25), (25, 25)], "name": "pier"}],
        keep_out_circles=[{"center_m": (11, 9), "radius_m": 2.5, "name": "rock"}],
        rally_points=[{"position_m": (0, 0), "name": "jetty"}, {"position_m": (30, 0)}],
    )


def assert_same_area(a: OperatingArea, b: OperatingArea, tol_m: float = 1e-6) -> None:
    """The same zones and points, coordinates within ``tol_m`` (degrees round-trip through ECEF)."""
    pairs = [(a.keep_in, b.keep_in), *zip(a.keep_out_polygons, b.keep_out_polygons, strict=True)]
    for p, q in pairs:
        assert len(p.vertices_m) == len(q.vertices_m)
        for u, v in zip(p.vertices_m, q.vertices_m, strict=True):
            assert math.dist(u, v) < tol_m
    for c, d in zip(a.keep_out_circles, b.keep_out_circles, strict=True):
        assert math.dist(c.center_m, d.center_m) < tol_m and c.radius_m == pytest.approx(d.radius_m)
    for r, s in zip(a.rally_points, b.rally_points, strict=True):
        assert math.dist(r.position_m, s.position_m) < tol_m
    assert len(a.rally_points) == len(b.rally_points)
    assert len(a.keep_out_circles) == len(b.keep_out_circles)


# -- TOML ----------------------------------------------------------------------------------------


def test_toml_round_trips_in_metres_and_in_degrees() -> None:
    for origin in (None, ORIGIN):
        spec = area_spec.spec_of(area(), origin)
        text = area_spec.to_toml(spec)
        back = area_spec.from_toml(text)
        assert back == spec
        assert_same_area(back.to_area(ORIGIN), area())
    assert "vertices_deg" in area_spec.to_toml(area_spec.spec_of(area(), ORIGIN))


def test_toml_as_written_by_hand() -> None:
    text = """
[area]
keep_in = { vertices_m = [[-5.0, -5.0], [30.0, -5.0], [30.0, 25.0], [-5.0, 25.0]] }
[[area.keep_out]]
center_m = [10.0, 9.0]
radius_m = 3.0
[[area.rally]]
position_deg = [28.18, 112.94]
name = "jetty"
"""
    result = area_spec.from_toml(text).to_area(ORIGIN)
    assert result.keep_out_circles[0].radius_m == 3.0
    assert math.dist(result.rally_points[0].position_m, (0.0, 0.0)) < 1e-6


@pytest.mark.parametrize(
    ("table", "named"),
    [
        ({"keep_in": {"center_m": [0.0, 0.0], "radius_m": 5.0}}, "keep_in"),
        ({"keep_out": [{"center_m": [0.0, 0.0]}]}, "radius_m"),
        (
            {"keep_out": [{"vertices_m": [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], "center_m": [0.0, 0.0]}]},
            "exactly one",
        ),
        ({"keep_out": [{"vertices_deg": [[95.0, 0.0], [1.0, 0.0], [0.0, 1.0]]}]}, "keep_out.0.vertices_deg"),
        ({"rally": [{}]}, "position_m"),
        ({"keep_in": {"vertices_m": [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]}, "colour": "red"}, "colour"),
    ],
)
def test_bad_toml_tables_are_refused_naming_the_field(table: dict, named: str) -> None:
    with pytest.raises(AreaError) as err:
        area_spec.parse_spec(table, "scenario [area]")
    assert named in str(err.value) and "scenario [area]" in str(err.value)


def test_degrees_without_an_origin_and_unreadable_toml_are_refused() -> None:
    with pytest.raises(AreaError, match="origin"):
        area_spec.spec_of(area(), ORIGIN).to_area(None)
    with pytest.raises(AreaError, match="not valid TOML"):
        area_spec.from_toml("[area\n")
    with pytest.raises(AreaError, match=r"no \[area\] table"):
        area_spec.from_toml("x = 1\n")


KEEP_IN = "[area.keep_in]\nvertices_m = [[-20, -20], [45, -20], [45, 40], [-20, 40]]\n"


@pytest.mark.parametrize("text, named", [
    (KEEP_IN + '[[keep_out]]\nname = "pier"\ncenter_m = [10.0, 0.0]\nradius_m = 3.0\n', "keep_out"),
    ("[area]\n[keep_in]\nvertices_m = [[-20, -20], [45, -20], [45, 40], [-20, 40]]\n", "keep_in"),
    (KEEP_IN + "[[rally]]\nposition_m = [0.0, 0.0]\n", "rally"),
])
def test_a_zone_written_outside_the_area_table_is_refused_not_dropped(text: str, named: str) -> None:
    """Without the "area." prefix a zone is a top-level table nobody reads: refused by name, so a
    keep-out the operator wrote is never silently left out of the check."""
    with pytest.raises(AreaError) as err:
        area_spec.from_toml(text, "lake.toml")
    assert named in str(err.value) and "[area." in str(err.value) and "lake.toml" in str(err.value)
    assert area_spec.from_toml(KEEP_IN).keep_in is not None  # the same file, written right, reads


def test_an_area_table_without_a_zone_is_refused() -> None:
    with pytest.raises(AreaError, match="keep_in"):
        area_spec.from_toml("[area]\n")


def test_an_area_valid_as_a_table_but_not_as_an_area_is_refused() -> None:
    table = {"keep_in": {"vertices_m": [[0, 0], [10, 10], [10, 0], [0, 10]]}}
    with pytest.raises(AreaError, match="cross"):
        area_spec.parse_spec(table).to_area(None)


# -- QGroundControl .plan ------------------------------------------------------------------------

# The layout QGroundControl writes (GeoFenceController, QGCFencePolygon, QGCFenceCircle,
# RallyPointController::save): geoFence version 2, each polygon/circle version 1, rally version 2.
QGC_SECTIONS = {
    "geoFence": {
        "circles": [
            {"circle": {"center": [47.3975, 8.5455], "radius": 12.5}, "inclusion": False, "version": 1}
        ],
        "polygons": [
            {
                "inclusion": True,
                "polygon": [[47.399, 8.544], [47.399, 8.547], [47.396, 8.547], [47.396, 8.544]],
                "version": 1,
            },
            {
                "inclusion": False,
                "polygon": [[47.3980, 8.5460], [47.3980, 8.5465], [47.3975, 8.5465]],
                "version": 1,
            },
        ],
        "version": 2,
    },
    "rallyPoints": {"points": [[47.3970, 8.5450, 15.0]], "version": 2},
}


def test_qgc_sections_read_into_keep_in_keep_out_and_rally_points() -> None:
    spec = plan.spec_from_plan(QGC_SECTIONS)
    assert spec is not None
    assert spec.keep_in.vertices_deg[0] == (47.399, 8.544)
    assert [z.is_circle for z in spec.keep_out] == [False, True]
    assert spec.keep_out[1].radius_m == 12.5
    assert spec.rally[0].position_deg == (47.397, 8.545)
    result = spec.to_area(GeoOrigin.from_degrees(47.3977, 8.5456))
    assert result.keep_in is not None and len(result.keep_out_polygons) == 1


def test_qgc_sections_round_trip() -> None:
    spec = plan.spec_from_plan(QGC_SECTIONS)
    fence, rally = plan.plan_sections(spec)
    assert plan.spec_from_plan({"geoFence": fence, "rallyPoints": rally}) == spec
    assert fence["version"] == 2 and rally["version"] == 2
    assert {p["version"] for p in fence["polygons"]} == {1}
    # An area in metres goes out through the origin and comes back the same.
    spec_deg = area_spec.spec_of(area(), ORIGIN)
    fence, rally = plan.plan_sections(spec_deg)
    back = plan.spec_from_plan({"geoFence": fence, "rallyPoints": rally})
    assert_same_area(back.to_area(ORIGIN), area())


def test_an_empty_plan_fence_is_no_area() -> None:
    assert (
        plan.spec_from_plan(
            {
                "geoFence": {"circles": [], "polygons": [], "version": 2},
                "rallyPoints": {"points": [], "version": 2},
            }
        )
        is None
    )
    assert plan.spec_from_plan({}) is None
    assert plan.plan_sections(None) == (
        {"circles": [], "polygons": [], "version": 2},
        {"points": [], "version": 2},
    )


def _broken(path: tuple, value: object) -> dict:
    doc = copy.deepcopy(QGC_SECTIONS)
    target = doc
    for k in path[:-1]:
        target = target[k]
    target[path[-1]] = value
    return doc


@pytest.mark.parametrize(
    ("doc", "named"),
    [
        (_broken(("geoFence", "version"), 1), "geoFence: version 1"),
        (_broken(("geoFence", "circles", 0, "inclusion"), True), "circles[0]: an inclusion circle"),
        (_broken(("geoFence", "polygons", 1, "inclusion"), True), "2 inclusion polygons"),
        (_broken(("geoFence", "polygons", 0, "polygon", 1), [91.0, 8.5]), "polygons[0] polygon[1]"),
        (_broken(("geoFence", "circles", 0, "circle", "radius"), -3), "keep_out.1.radius_m"),
        (
            _broken(
                ("geoFence", "polygons", 0, "polygon"),
                [[47.399, 8.544], [47.396, 8.547], [47.399, 8.547], [47.396, 8.544]],
            ),
            "cross",
        ),
        (_broken(("rallyPoints", "points", 0), [100.0, 8.5, 0.0]), "rallyPoints.points[0]"),
        (_broken(("rallyPoints", "points", 0), [47.5, 8.5, 0.0]), "rally_points[0]"),
        (_broken(("geoFence", "polygons", 0, "inclusion"), "yes"), "inclusion must be true or false"),
    ],
)
def test_bad_plan_fences_are_refused_naming_the_item(doc: dict, named: str) -> None:
    with pytest.raises(AreaError) as err:
        spec = plan.spec_from_plan(doc)
        spec.to_area(GeoOrigin.from_degrees(47.3977, 8.5456))
    assert named in str(err.value)


# -- GeoJSON -------------------------------------------------------------------------------------


def test_geojson_round_trips_with_circles_as_points_with_a_radius() -> None:
    spec = area_spec.spec_of(area(), ORIGIN)
    doc = json.loads(json.dumps(geojson.to_geojson(spec)))
    kinds = [(x["geometry"]["type"], x["properties"]["area"]) for x in doc["features"]]
    assert kinds == [
        ("Polygon", "keep_in"),
        ("Polygon", "keep_out"),
        ("Point", "keep_out"),
        ("Point", "rally"),
        ("Point", "rally"),
    ]
    ring = doc["features"][0]["geometry"]["coordinates"][0]
    assert ring[0] == ring[-1]  # RFC 7946: closed rings
    assert geojson.spec_from_geojson(doc) == spec
    assert_same_area(geojson.spec_from_geojson(doc).to_area(ORIGIN), area())


def test_geojson_without_area_features_has_no_area() -> None:
    line = {
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": [[8, 47], [8.1, 47]]},
        "properties": {},
    }
    assert geojson.spec_from_geojson(line) is None
    assert geojson.spec_from_geojson({"type": "FeatureCollection", "features": [line]}) is None


def _feature(geometry: dict, **props: object) -> dict:
    return {
        "type": "FeatureCollection",
        "features": [{"type": "Feature", "geometry": geometry, "properties": props}],
    }


SQUARE_RING = [[[8.0, 47.0], [8.001, 47.0], [8.001, 47.001], [8.0, 47.001], [8.0, 47.0]]]


@pytest.mark.parametrize(
    ("doc", "named"),
    [
        (
            _feature({"type": "Polygon", "coordinates": SQUARE_RING}, area="keepin"),
            "keep_in, keep_out, rally",
        ),
        (_feature({"type": "Polygon", "coordinates": SQUARE_RING * 2}, area="keep_in"), "holes"),
        (_feature({"type": "Polygon", "coordinates": [SQUARE_RING[0][:-1]]}, area="keep_in"), "repeat"),
        (_feature({"type": "LineString", "coordinates": SQUARE_RING[0]}, area="keep_out"), "Polygon"),
        (_feature({"type": "Point", "coordinates": [8.0, 47.0]}, area="keep_out"), "properties.radius_m"),
        (_feature({"type": "Polygon", "coordinates": SQUARE_RING}, area="rally"), "must be a Point"),
        (_feature({"type": "Point", "coordinates": [200.0, 47.0]}, area="rally"), "longitude"),
    ],
)
def test_bad_geojson_area_features_are_refused_naming_the_feature(doc: dict, named: str) -> None:
    with pytest.raises(AreaError) as err:
        geojson.spec_from_geojson(doc)
    assert named in str(err.value) and "features[0]" in str(err.value)


# -- files by suffix -----------------------------------------------------------------------------


def test_an_area_file_is_read_by_its_suffix(tmp_path) -> None:
    spec = area_spec.spec_of(area(), ORIGIN)
    (tmp_path / "a.toml").write_text(area_spec.to_toml(spec))
    fence, rally = plan.plan_sections(spec)
    (tmp_path / "a.plan").write_text(
        json.dumps({"fileType": "Plan", "geoFence": fence, "rallyPoints": rally})
    )
    (tmp_path / "a.geojson").write_text(json.dumps(geojson.to_geojson(spec)))
    for name in ("a.toml", "a.geojson"):
        assert files.load_area_file(tmp_path / name) == spec, name
    assert_same_area(files.load_area_file(tmp_path / "a.plan").to_area(ORIGIN), area())  # .plan: no names
    (tmp_path / "empty.plan").write_text(json.dumps({"fileType": "Plan"}))
    assert files.load_area_file(tmp_path / "empty.plan") is None


def test_an_unreadable_area_file_is_refused_naming_it(tmp_path) -> None:
    (tmp_path / "a.txt").write_text("x")
    (tmp_path / "bad.plan").write_text("{")
    (tmp_path / "bad.geojson").write_text(
        json.dumps(_feature({"type": "Point", "coordinates": [8, 47]}, area="moat"))
    )
    for name, named in (
        ("a.txt", "unknown file type"),
        ("bad.plan", "not JSON"),
        ("missing.toml", "cannot read"),
        ("bad.geojson", "features[0]"),
    ):
        with pytest.raises(AreaError) as err:
            files.load_area_file(tmp_path / name)
        assert named in str(err.value) and name in str(err.value)


@pytest.mark.parametrize(("name", "text", "named"), [
    ("bigint.toml", "[area]\nx = 1" + "0" * 5000 + "\n", "a number too long to read"),
    ("bigint.plan", '{"fileType": "Plan", "x": 1' + "0" * 5000 + "}", "a number too long to read"),
    ("deep.toml", "[area]\nx = " + "[" * 3000 + "]" * 3000 + "\n", "nested too deeply"),
    ("deep.geojson", '{"x": ' + "[" * 3000 + "]" * 3000 + "}", "nested too deeply"),
])
def test_a_file_the_parser_chokes_on_is_refused_naming_it(tmp_path, name, text, named) -> None:
    """A 5000-digit number (ValueError) or nesting 3000 deep (RecursionError) escaped as a
    traceback."""
    (tmp_path / name).write_text(text)
    with pytest.raises(AreaError, match=rf"{name}: not a usable document: {named}"):
        files.load_area_file(tmp_path / name)


@pytest.mark.parametrize(("name", "data", "named"), [
    # the mission reader refused these in the same file; the area reader took them
    ("twice.plan", b'{"fileType": "Plan", "geoFence": {}, "geoFence": {"version": 2}}',
     "appears more than once"),
    ("nan.geojson", b'{"type": "FeatureCollection", "features": [], "x": NaN}',
     "NaN is not a number JSON allows"),
    ("utf16.plan", '{"fileType": "Plan"}'.encode("utf-16"), "not UTF-8"),
])
def test_area_json_is_read_as_strictly_as_the_mission_in_the_same_file(tmp_path, name, data,
                                                                      named) -> None:
    (tmp_path / name).write_bytes(data)
    with pytest.raises(AreaError, match=named) as err:
        files.load_area_file(tmp_path / name)
    assert name in str(err.value)


def test_an_area_file_past_the_size_bound_is_refused_unread(tmp_path) -> None:
    """Bounded like a mission file (``seaway.json_files.MAX_FILE_BYTES``): a larger file is refused
    after that many bytes, not read whole."""
    from seaway import json_files

    path = tmp_path / "huge.geojson"
    path.write_bytes(b" " * json_files.MAX_FILE_BYTES + b"{}")
    with pytest.raises(AreaError, match=f"larger than the {json_files.MAX_FILE_BYTES} bytes"):
        files.load_area_file(path)
