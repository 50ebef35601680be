"""Mission files crafted to break the reader (seaway.mission_files): each is read as the mission
the file gives, or refused with a PlanError naming what is wrong and what is allowed; nothing else
escapes (the ground station answers 422, never 500), and time and memory stay bounded before the
waypoint count is known."""

from __future__ import annotations

import contextlib
import copy
import json
import re
import time
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from seaway import mission_export
from seaway import mission_files as plans
from seaway.contract import keys
from seaway.contract.messages import Reply
from seaway.mission_files import PlanError
from seaway.runtime.memory_bus import MemoryHub
from seaway_groundstation.app import create_app
from seaway_groundstation.settings import Settings

LINE = {"type": "LineString", "coordinates": [[8.0, 47.0], [8.001, 47.0]]}


def plan(points: list[tuple[float, float]] | None = None) -> dict[str, Any]:
    """A plan as QGroundControl writes it, through JSON (as a reader gets it)."""
    doc = mission_export.to_plan(points or [(47.0, 8.0), (47.001, 8.0), (47.001, 8.001)], coa_radius_m=2.0)
    return json.loads(json.dumps(doc))


def item(command: int, params: list[Any]) -> dict[str, Any]:
    return {"type": "SimpleItem", "command": command, "frame": 3, "params": params,
            "autoContinue": True, "doJumpId": 9}


# -- the text: size, encoding, duplicate keys, literals -----------------------------------------


def test_a_file_over_the_byte_bound_is_refused_before_it_is_parsed() -> None:
    """A 200 MB GeoJSON took 15 s and 2 GB in ``seaway mission check`` before its 8 million
    waypoints were counted and refused."""
    doc = json.dumps(LINE).encode()
    assert plans.load_json(doc, max_bytes=len(doc)) == LINE
    with pytest.raises(PlanError, match=f"{len(doc) + 1} bytes, more than the {len(doc)}"):
        plans.load_json(doc + b" ", max_bytes=len(doc))
    assert plans.MAX_FILE_BYTES >= 1 << 20  # room for a plan of MAX_WAYPOINTS waypoints, and more


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-32"])
def test_utf16_and_utf32_text_are_refused_naming_the_encoding(encoding: str) -> None:
    with pytest.raises(PlanError, match=f"(?i){encoding}.*not UTF-8"):
        plans.load_json(json.dumps(LINE).encode(encoding))


def test_utf8_with_a_byte_order_mark_and_crlf_lines_is_read() -> None:
    text = json.dumps(LINE, indent=2).replace("\n", "\r\n")
    assert plans.load_json(b"\xef\xbb\xbf" + text.encode()) == LINE


def test_a_key_given_twice_is_refused_naming_it() -> None:
    """Python kept the last "coordinates" and flew it; another tool may show the first."""
    raw = b'{"type": "LineString", "coordinates": [[0, 0], [1, 1]], "coordinates": [[8, 47], [8.1, 47]]}'
    with pytest.raises(PlanError, match=r'"coordinates".*more than once'):
        plans.load_json(raw)
    with pytest.raises(PlanError, match='"command"'):
        plans.load_json(b'{"mission": {"items": [{"command": 16, "command": 22}]}}')


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity"])
def test_nan_literals_are_refused_as_such(literal: str) -> None:
    """The refusal said "a number too long to read" (the PlanError was caught as a ValueError)."""
    with pytest.raises(PlanError) as err:
        plans.load_json(f'{{"a": {literal}}}')
    assert literal in str(err.value) and "too long" not in str(err.value)


@pytest.mark.parametrize("raw, where", [
    (b'{"type": "LineString", "coordinates": [[1e400, 47], [8, 47]]}', "coordinates[0] longitude"),
    (b'{"type": "LineString", "coordinates": [[8, 47], [8, ' + b"9" * 400 + b"]]}",
     "coordinates[1] latitude"),
    (b'{"type": "LineString", "coordinates": [["8", 47], [8, 47]]}', "coordinates[0] longitude"),
])
def test_numbers_beyond_a_float_or_as_text_are_refused_naming_the_position(raw: bytes, where: str) -> None:
    with pytest.raises(PlanError, match=f"{re.escape(where)}.*finite number"):
        plans.parse_document(plans.load_json(raw))


# -- coordinates that are odd but real ------------------------------------------------------------


def test_poles_antimeridian_and_negative_zero_are_read_as_written() -> None:
    """The reader neither wraps nor rejects them: whether the vessel can fly there is the
    check's (``seaway mission check``: distance from the origin, the operating area)."""
    for points in ([(90.0, 0.0), (-90.0, 180.0)], [(10.0, 179.9999), (10.0, -179.9999)],
                   [(-0.0, -0.0), (0.0, 0.001)]):
        assert plans.parse_plan(plan(points)).points_deg == tuple(points)


# -- plans: items the reader does not fly, and malformed ones ------------------------------------


@pytest.mark.parametrize("bad", [[3], {"frame": 3}, False, "3"])
def test_a_frame_of_another_json_type_is_refused(bad: Any) -> None:
    """A list or an object raised TypeError (unhashable; a 500 from the API) and false was taken
    as frame 0, GLOBAL."""
    doc = plan()
    doc["mission"]["items"][1]["frame"] = bad
    with pytest.raises(PlanError, match=r"items\[1\].*frame .* global frame \(0 GLOBAL"):
        plans.parse_plan(doc)


def test_a_waypoint_hold_time_is_refused_or_said_to_be_flown_through() -> None:
    """A 30 s hold was dropped silently: the vessel passed through a waypoint the file holds at."""
    doc = plan()
    doc["mission"]["items"][1]["params"][0] = 30
    with pytest.raises(PlanError, match=r"items\[1\].*hold time params\[0\] 30 s.*skip_unsupported"):
        plans.parse_plan(doc)
    path = plans.parse_plan(doc, skip_unsupported=True)
    assert len(path.points_deg) == 3  # the waypoint is flown, without the hold
    assert len(path.skipped) == 1 and "items[1]" in path.skipped[0] and "hold" in path.skipped[0]
    for bad in ("30", -1, [30]):
        doc["mission"]["items"][1]["params"][0] = bad
        with pytest.raises(PlanError, match=r"items\[1\].*hold time params\[0\].*seconds"):
            plans.parse_plan(doc, skip_unsupported=True)
    doc["mission"]["items"][1]["params"][0] = None  # QGroundControl's NaN: no hold
    assert plans.parse_plan(doc).skipped == ()


@pytest.mark.parametrize("command, params, effect", [
    (17, [0, 0, 10, 0, 47.0005, 8.0005, 0], "position"),  # NAV_LOITER_UNLIM, with a position
    (177, [1, 3, 0, 0, 0, 0, 0], "once"),                 # DO_JUMP to item 1, 3 times
    (179, [0, 0, 0, 0, 10.0, 10.0, 0], "home"),           # DO_SET_HOME, far away
])
def test_commands_not_flown_are_refused_or_skipped_saying_what_changes(command: int, params: list[Any],
                                                                       effect: str) -> None:
    doc = plan()
    doc["mission"]["items"].insert(1, item(command, params))
    with pytest.raises(PlanError, match=rf"items\[1\].*command {command}.*{effect}.*skip_unsupported"):
        plans.parse_plan(doc)
    path = plans.parse_plan(doc, skip_unsupported=True)
    assert path.points_deg == plans.parse_plan(plan()).points_deg  # the waypoints, once, in order
    assert len(path.skipped) == 1 and effect in path.skipped[0]


def test_planned_home_is_not_read() -> None:
    doc = plan()
    doc["mission"]["plannedHomePosition"] = [0.0, 0.0, 0.0]  # 5,000 km from the waypoints
    assert plans.parse_plan(doc) == plans.parse_plan(plan())


def test_a_speed_change_without_seven_params_is_refused_naming_them() -> None:
    """It was refused as "speed null", a value the file does not hold."""
    doc = plan()
    doc["mission"]["items"].insert(1, item(178, [1, 2.0]))
    with pytest.raises(PlanError, match=r"items\[1\].*DO_CHANGE_SPEED.*params must be a list of 7"):
        plans.parse_plan(doc)


def test_a_plan_of_too_many_items_is_refused_before_they_are_read_and_listed() -> None:
    """A million unsupported items with skip_unsupported took 1.7 s and listed a million lines."""
    doc = plan()
    takeoff = item(22, [0] * 7)
    bound = plans.MAX_ITEMS_PER_WAYPOINT * 3
    doc["mission"]["items"] += [takeoff] * (bound - 3)
    assert len(plans.parse_plan(doc, skip_unsupported=True, max_waypoints=3).skipped) == bound - 3
    doc["mission"]["items"].append(takeoff)
    with pytest.raises(PlanError, match=f"{bound + 1} mission items, more than the {bound}"):
        plans.parse_plan(doc, skip_unsupported=True, max_waypoints=3)


def test_a_refusal_quotes_a_long_value_only_in_part() -> None:
    doc = plan()
    doc["mission"]["items"][0]["type"] = "x" * 100_000
    with pytest.raises(PlanError) as err:
        plans.parse_plan(doc)
    assert "items[0]" in str(err.value) and len(str(err.value)) < 300


# -- GeoJSON ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("crs", [{"type": "name", "properties": "EPSG:4326"},
                                 {"type": "name", "properties": [1]}, "EPSG:4326", 4326])
def test_a_crs_of_another_shape_is_refused(crs: Any) -> None:
    """A crs whose properties were not an object raised AttributeError (a 500 from the API)."""
    with pytest.raises(PlanError, match=r"crs .* is not WGS84"):
        plans.parse_geojson({**LINE, "crs": crs})


@pytest.mark.parametrize("properties", [[1], "coa_radius_m=2", 2.0, True])
def test_feature_properties_not_an_object_are_refused(properties: Any) -> None:
    """They were ignored, with any mission parameters meant to be in them."""
    with pytest.raises(PlanError, match="properties: expected an object or null"):
        plans.parse_geojson({"type": "Feature", "geometry": LINE, "properties": properties})
    assert plans.parse_geojson({"type": "Feature", "geometry": LINE, "properties": None}).hints == {}


def test_a_long_linestring_is_refused_by_count_before_its_positions_are_read() -> None:
    coords = [[8.0, 47.0]] * 10 + [[999.0, 999.0]]
    with pytest.raises(PlanError, match="11 waypoints, more than the 10 allowed"):
        plans.parse_geojson({"type": "LineString", "coordinates": coords}, max_waypoints=10)
    started = time.perf_counter()
    with pytest.raises(PlanError, match="more than the 1000 allowed"):
        plans.parse_geojson({"type": "LineString", "coordinates": [[8.0, 47.0]] * 1_000_000})
    assert time.perf_counter() - started < 0.5


def test_collections_with_several_or_multi_lines_are_refused_saying_what_was_left_out() -> None:
    feature = {"type": "Feature", "geometry": LINE, "properties": {}}
    multi = {"type": "Feature", "properties": {},
             "geometry": {"type": "MultiLineString", "coordinates": [LINE["coordinates"]]}}
    with pytest.raises(PlanError, match=r"holds 2 LineString features \(at features\[0\], features\[1\]\)"):
        plans.parse_geojson({"type": "FeatureCollection", "features": [feature, feature]},
                            skip_unsupported=True)
    with pytest.raises(PlanError, match=r"holds 0 LineString.*skipped.*features\[0\].*MultiLineString"):
        plans.parse_geojson({"type": "FeatureCollection", "features": [multi]}, skip_unsupported=True)
    with pytest.raises(PlanError, match="\"MultiLineString\" is not supported"):
        plans.parse_geojson(multi["geometry"])


def test_3d_positions_are_read_and_others_refused() -> None:
    assert plans.parse_geojson({"type": "LineString", "coordinates": [[8, 47, 5.0], [8.001, 47, -3]]}
                               ).points_deg == ((47.0, 8.0), (47.0, 8.001))
    with pytest.raises(PlanError, match=r"coordinates\[0\] must be \[lon, lat\] or \[lon, lat, alt\]"):
        plans.parse_geojson({"type": "LineString", "coordinates": [[8, 47, 0, 0], [8.001, 47]]})


# -- the ground station answers these with 422 and stays up --------------------------------------


@pytest.fixture
def client() -> Iterator[TestClient]:
    hub = MemoryHub()
    vessel = hub.bus("v1")
    for service in ("vehicle_io", "controller", "estimator"):
        vessel.declare_alive(service)
    vessel.queryable(keys.MISSION_SET, lambda req: Reply.accept(1, "mission/set done"))
    settings = Settings(token="test-token-0123456789abcdef", request_timeout_s=2.0)
    with TestClient(create_app(hub.bus("gs"), settings), raise_server_exceptions=False) as c:
        yield c
    vessel.close()


def test_the_import_answers_crafted_files_with_422_and_goes_on(client: TestClient) -> None:
    auth = {"Authorization": "Bearer test-token-0123456789abcdef"}
    frame_list = plan()
    frame_list["mission"]["items"][0]["frame"] = [3]
    crafted = [json.dumps(frame_list).encode(), json.dumps({**LINE, "crs": {"properties": "x"}}).encode(),
               json.dumps(plan()).encode("utf-16"),
               b'{"type": "LineString", "coordinates": [[0, 0], [1, 1]], '
               b'"coordinates": [[8, 47], [8.1, 47]]}']
    for data in crafted:
        r = client.post("/api/vessels/v1/mission/import", headers=auth,
                        files={"file": ("m.plan", data)}, data={"task_power_w": "1", "coa_radius_m": "2"})
        assert r.status_code == 422, r.text
    for doc in crafted[:2]:
        parsed = client.post("/api/missions/parse", json={"document": json.loads(doc)})
        assert parsed.status_code == 422, parsed.text
    ok = client.post("/api/vessels/v1/mission/import", headers=auth,
                     files={"file": ("m.plan", json.dumps(plan()).encode())}, data={"task_power_w": "1"})
    assert ok.status_code == 200, ok.text


def test_no_other_exception_escapes_the_reader() -> None:
    """Every value of a few JSON types at every place of a plan and a GeoJSON document with an
    area: the reader returns or raises PlanError."""
    fence = {"version": 2, "circles": [{"circle": {"center": [47, 8], "radius": 3.0}, "inclusion": False,
                                         "version": 1}],
             "polygons": [{"inclusion": True, "version": 1,
                           "polygon": [[46.9, 7.9], [46.9, 8.1], [47.1, 8.1], [47.1, 7.9]]}]}
    a_plan = {**plan(), "geoFence": fence, "rallyPoints": {"version": 2, "points": [[47, 8, 0]]}}
    a_plan["mission"]["items"].insert(1, item(178, [1, 2.0, -1, 0, 0, 0, 0]))
    collection = {"type": "FeatureCollection",
                  "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:OGC:1.3:CRS84"}},
                  "features": [{"type": "Feature", "geometry": LINE,
                                "properties": {"coa_radius_m": 2, "speeds_mps": [1, None]}},
                               {"type": "Feature", "properties": {"area": "rally"},
                                "geometry": {"type": "Point", "coordinates": [8, 47]}}]}
    values = [None, True, False, 0, -1, 1e308, "x", [], {}, [1], {"a": 1}, [None] * 7, 16]

    def places(node: Any, at: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
        if at:
            yield at
        children = (node.items() if isinstance(node, dict) else
                    enumerate(node) if isinstance(node, list) else ())
        for key, child in children:
            yield from places(child, (*at, key))

    for doc in (a_plan, collection):
        for at in places(doc):
            for value in values:
                changed = copy.deepcopy(doc)
                parent = changed
                for key in at[:-1]:
                    parent = parent[key]
                parent[at[-1]] = value
                for skip in (False, True):
                    with contextlib.suppress(PlanError):
                        plans.parse_document(changed, skip_unsupported=skip)
