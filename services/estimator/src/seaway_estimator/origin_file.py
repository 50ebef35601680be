"""The NED origin a real boat's estimator took from its first fix, kept across a restart.

Without a configured origin (a boat: ``RunDescription.origin`` None) the estimator takes its first
good GNSS fix as the origin of the local NED frame every position on the bus is in. A restarted
estimator would take its first fix again, wherever the vessel is by then, and move the frame under
the mission, the operating area and the home, which the controller holds in local metres: a boat
200 m out when the estimator crashed would have flown its next waypoint 200 m too far. So the origin
is written to ``--state-file`` once taken, as the ``NavOrigin`` it publishes stamped with the wall time
it was saved (atomically and durably, ``seaway.runtime.atomic``), and a
restarted estimator of the same run starts from it. A file saved before the run began (an earlier
launch into the same folder) is not used; a file that cannot be read is logged and not used.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

from seaway.contract.messages import NavOrigin
from seaway.runtime import atomic
from seaway.runtime.run import from_earlier_launch
from seaway.vessel.frames import GeoOrigin

log = logging.getLogger("seaway.estimator")


def load(path: Path, run_file: str | Path | None) -> GeoOrigin | None:
    """The origin kept at ``path`` by this run's estimator, else None (no file, one from an
    earlier launch, or one that cannot be used: logged)."""
    try:
        kept = atomic.read_model(path, NavOrigin)
    except atomic.StateFileError as err:
        log.error("not using the kept NED origin: %s; taking the first good fix instead", err)
        return None
    if kept is None:
        return None
    if from_earlier_launch(kept.stamp_ns, run_file):
        log.info("kept NED origin %s was saved before this run started (an earlier launch into "
                 "this folder): taking the first good fix instead", path)
        return None
    return GeoOrigin(kept.lat_rad, kept.lon_rad, kept.alt_m)


def save(path: Path, origin: GeoOrigin) -> None:
    """Keep ``origin`` at ``path`` (atomically, on disk before it replaces the old one)."""
    kept = NavOrigin(stamp_ns=time.time_ns(), lat_rad=origin.lat_rad, lon_rad=origin.lon_rad,
                     alt_m=origin.alt_m)
    atomic.write_text(path, kept.encode().decode())
