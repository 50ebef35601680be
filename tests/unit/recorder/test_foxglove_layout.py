"""The shipped Foxglove layout (deploy/foxglove/seaway.json) names only what a recording has: every
plotted path is a field of its key's message type, every panel's topic one the recorder derives."""

from __future__ import annotations

import json
from pathlib import Path

from seaway.contract import keys
from seaway.contract.messages import MissionAccepted, NavOrigin, SimTruth, SolveRecord, StateEstimate
from seaway.vessel.frames import GeoOrigin
from seaway_recorder.derive import LOG_TOPIC, FoxgloveDeriver

LAYOUT = Path(__file__).resolve().parents[3] / "deploy" / "foxglove" / "seaway.json"
V = "vessel1"


def derived_topics() -> set[str]:
    """Every topic the deriver makes for vessel1 from one message of each source."""
    d = FoxgloveDeriver(GeoOrigin.from_degrees(47.0, 8.0))
    msgs = [(keys.NAV_ORIGIN, NavOrigin.make(stamp_ns=0, lat_rad=0.8, lon_rad=0.1, alt_m=0.0)),
            (keys.SIM_TRUTH, SimTruth.make(stamp_ns=1, u_mps=0, v_mps=0, r_radps=0, x_m=0, y_m=0,
                                           psi_rad=0, thrust_port_n=0, thrust_starboard_n=0,
                                           energy_j=0)),
            (keys.NAV_STATE, StateEstimate.make(stamp_ns=1, u_mps=0, v_mps=0, r_radps=0, x_m=0, y_m=0,
                                                psi_rad=0)),
            (keys.SOLVE, SolveRecord.make(stamp_ns=1, controller="cc-empc", status="ok", success=True,
                                          iterations=1, solve_time_s=0.0, predicted_x_m=[0.0, 1.0],
                                          predicted_y_m=[0.0, 0.0])),
            (keys.MISSION_ACCEPTED, MissionAccepted.make(
                stamp_ns=1, accepted_ns=1, waypoints=[{"x_m": 0, "y_m": 0}, {"x_m": 5, "y_m": 0}],
                coa_radius_m=1.0, task_power_w=1.0, controller="cc-empc", predict_disturbance=False))]
    return {x.topic for spec, m in msgs for x in d.feed(spec.key(V), m)} | {LOG_TOPIC}


def test_layout_panels_and_paths_exist() -> None:
    doc = json.loads(LAYOUT.read_text())
    cfg = doc["configById"]
    kinds = sorted(pid.split("!")[0] for pid in cfg)
    assert kinds == ["3D", "Plot", "Plot", "Plot", "Plot", "RosOut", "map"]

    def panels(node) -> list[str]:
        return [node] if isinstance(node, str) else panels(node["first"]) + panels(node["second"])

    assert sorted(panels(doc["layout"])) == sorted(cfg)  # every panel placed, none missing

    topics = derived_topics()
    by_key = {spec.key(V): spec.message for spec in keys.REGISTRY if spec.message is not None}
    titles = []
    for pid, c in cfg.items():
        if pid.startswith("Plot!"):
            titles.append(c["title"])
            for path in c["paths"]:
                topic, field = path["value"].rsplit(".", 1)
                assert field in by_key[topic].model_fields, path["value"]
                assert path["timestampMethod"] == "receiveTime"  # the log time: sim time in lockstep
    assert sorted(titles) == ["Cross-track error [m]", "Energy [J]", "Speed [m/s]", "Thrust [N]"]
    assert cfg["RosOut!log"]["topicToRender"] in topics
    assert set(cfg["3D!seaway"]["topics"]) <= topics
    assert cfg["map!seaway"]["followTopic"] in topics
    assert set(cfg["map!seaway"]["topicColors"]) <= topics
