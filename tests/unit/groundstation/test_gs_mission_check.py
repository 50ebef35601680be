"""``POST /api/missions/check?vessel=V`` (issue #57 item 3): the controller's own check
against the vessel's live state as the ground station knows it; a bad body is refused naming the
field. Over the in-memory bus, the vessel played by ``test_gs_api``'s responder."""

from __future__ import annotations

from fastapi.testclient import TestClient
from seaway.area.model import OperatingArea
from seaway.contract import keys
from seaway.contract.messages import ActiveArea

from tests.unit.groundstation.test_gs_api import AUTH, Vessel, client, hub, state, vessel  # noqa: F401

BOX = OperatingArea.make(keep_in={"name": "pond", "vertices_m": [(-10, -10), (30, -10), (30, 30),
                                                                  (-10, 30)]})


def body(points, **extra):
    return {"waypoints": [{"x_m": x, "y_m": y} for x, y in points], "coa_radius_m": 2.0,
            "task_power_w": 250.0, **extra}


def test_the_check_uses_the_live_state_and_the_area_enforced(client: TestClient,  # noqa: F811
                                                             vessel: Vessel) -> None:  # noqa: F811
    vessel.publish(keys.NAV_STATE, state(4.0))  # at (4, 2)
    vessel.publish(keys.AREA_ACTIVE, ActiveArea.of_area(BOX, stamp_ns=5, since_ns=5, source="pond"))
    r = client.post("/api/missions/check?vessel=v1", headers=AUTH,
                    json=body([(0, 0), (20, 0), (40, 0)]))
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["verdict"] == "refused" and out["live"] and out["area"] == "refused"
    assert "leg 1->2 leaves the keep-in area at north 30.0 m" in out["reasons"][0]
    assert out["area_source"] == "pond"
    # From (4, 2) to P_0, then the legs.
    assert out["path_length_m"] > 40.0
    ok = client.post("/api/missions/check?vessel=v1", headers=AUTH,
                     json=body([(0, 0), (20, 0)], battery_j=500000.0)).json()
    assert ok["verdict"] == "ok" and ok["battery_after_j"] < 500000.0
    assert client.post("/api/missions/check?vessel=v1", headers=AUTH, json=body(
        [(0, 0), (20, 0)], coa_radius_m=10000.0)).json()["verdict"] == "refused"
    # Nothing was sent.
    assert "mission/set" not in vessel.requests


def test_a_bad_body_is_422_naming_the_field(client: TestClient, vessel: Vessel) -> None:  # noqa: F811
    vessel.publish(keys.NAV_STATE, state(4.0))
    for bad, field in ((body([(0, 0)]), "waypoints"), (body([(0, 0), (1, 1)], force="maybe"), "force"),
                       (body([(0, 0), (1, 1)], battery_j=-1), "battery_j"),
                       (body([(0, 0), (1, 1)], extra=1), "extra")):
        r = client.post("/api/missions/check?vessel=v1", headers=AUTH, json=bad)
        assert r.status_code == 422 and field in r.text, (field, r.text)
    assert client.post("/api/missions/check?vessel=nobody", headers=AUTH,
                       json=body([(0, 0), (1, 1)])).status_code == 404
    desk = client.post("/api/missions/check", json=body([(0, 0), (20, 0)])).json()
    assert desk["verdict"] == "ok" and not desk["live"] and desk["against"] == "the desk"


def test_a_mission_sent_carries_its_start_and_rest_options_validated(client: TestClient,  # noqa: F811
                                                                     vessel: Vessel) -> None:  # noqa: F811
    r = client.post("/api/vessels/v1/mission", headers=AUTH,
                    json=body([(0, 0), (20, 0)], join_first_leg=True, at_rest="drift", force=True))
    assert r.status_code == 200, r.text
    sent = vessel.requests["mission/set"][-1]
    assert sent.join_first_leg and sent.at_rest == "drift" and sent.force
    bad = client.post("/api/vessels/v1/mission", headers=AUTH,
                      json=body([(0, 0), (20, 0)], at_rest="float"))
    assert bad.status_code == 422 and "at_rest" in bad.text
