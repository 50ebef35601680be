"""The NED origin a boat's estimator keeps for its restart (``seaway_estimator.origin_file``)."""

from __future__ import annotations

import logging
import os
from pathlib import Path

from seaway.vessel.frames import GeoOrigin
from seaway_estimator import origin_file
from seaway_estimator.config import EstimatorConfig
from seaway_estimator.core import EstimatorCore
from seaway_estimator.node import EstimatorNode

HERE = GeoOrigin.from_degrees(47.3, 8.5, 410.0)


def test_the_origin_kept_is_the_origin_read_back_in_the_same_run(tmp_path: Path) -> None:
    run = tmp_path / "run.json"
    run.write_text("{}")
    os.utime(run, ns=(1, 1))  # the run started long before the origin was kept
    kept = tmp_path / "estimator-state.json"
    origin_file.save(kept, HERE)
    back = origin_file.load(kept, run)
    assert back is not None
    assert (back.lat_rad, back.lon_rad, back.alt_m) == (HERE.lat_rad, HERE.lon_rad, HERE.alt_m)


def test_an_origin_kept_by_an_earlier_launch_or_unreadable_is_not_used(tmp_path: Path, caplog
                                                                       ) -> None:
    kept = tmp_path / "estimator-state.json"
    origin_file.save(kept, HERE)
    run = tmp_path / "run.json"
    run.write_text("{}")  # written after the origin was kept: a later launch into the folder
    os.utime(run, ns=(2**62, 2**62))
    assert origin_file.load(kept, run) is None
    assert origin_file.load(tmp_path / "none.json", run) is None
    for text in ("{", '{"stamp_ns": 1, "lat_rad": 9.0, "lon_rad": 0.1, "alt_m": 0.0}'):
        kept.write_text(text)
        with caplog.at_level(logging.ERROR, logger="seaway.estimator"):
            assert origin_file.load(kept, None) is None
        assert str(kept) in caplog.text
        caplog.clear()


def test_the_node_keeps_each_origin_taken_from_a_fix_and_none_configured() -> None:
    from seaway.contract.messages import Attitude, GnssFix

    kept: list[GeoOrigin] = []
    core = EstimatorCore(EstimatorConfig())
    node = EstimatorNode(core, keep_origin=kept.append)
    t = 1_000_000_000
    node.outputs(t, 0.0)
    assert kept == []  # no fix, no origin
    core.on_gnss(GnssFix(stamp_ns=t, lat_rad=HERE.lat_rad, lon_rad=HERE.lon_rad, alt_m=410.0,
                         fix_type=3, horizontal_std_m=0.5))
    core.on_attitude(Attitude(stamp_ns=t, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0,
                              roll_rate_radps=0.0, pitch_rate_radps=0.0, yaw_rate_radps=0.0))
    for k in range(3):
        node.outputs(t + k, 0.0)
    assert len(kept) == 1 and kept[0] is core.origin  # once, not at every period
    core.reset(keep_origin=False)  # the operator forgot it: the next fix is a new origin, kept
    core.on_gnss(GnssFix(stamp_ns=t + 10, lat_rad=HERE.lat_rad + 1e-5, lon_rad=HERE.lon_rad,
                         alt_m=410.0, fix_type=3, horizontal_std_m=0.5))
    node.outputs(t + 10, 0.0)
    assert len(kept) == 2 and kept[1].lat_rad == HERE.lat_rad + 1e-5
    fixed = EstimatorCore(EstimatorConfig(origin={"lat_deg": 47.0, "lon_deg": 8.0}))
    saved: list[GeoOrigin] = []
    EstimatorNode(fixed, keep_origin=saved.append).outputs(t, 0.0)
    assert saved == []  # the run's own origin is no origin to keep
