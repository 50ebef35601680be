"""Where the simulated vessel is, kept for the sim that replaces it (real time, ``--state-file``).

A real boat does not teleport: a restarted autopilot (or its link) finds the vessel where it was,
with the energy it had left. A restarted real-time sim started its scenario afresh, the vessel back
at its start pose with a full battery, and the mission then flew from there. So the real-time loop
keeps the plant's state at ``plant_path(state_file)`` (beside the kept scenario of
``seaway_sim.kept``), written every ``SAVE_EVERY_S`` of simulated time on a writer thread of its own
(``seaway.runtime.atomic.LatestWriter``: the loop never waits for the disk), and a sim that starts
while the file exists, for the same scenario (name and seed) and this run, puts the vessel back
there: pose, velocities, propulsion energy used and the battery drawn (its hotel time). Time itself
starts again at 0, as for any restart.

Lockstep keeps nothing: a restarted lockstep sim starts a new episode from t = 0, by design
(``seaway.runtime.lockstep``), and its runs stay deterministic.
"""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

from pydantic import Field
from seaway.contract.config import ConfigModel
from seaway.runtime import atomic
from seaway.runtime.run import from_earlier_launch

from seaway_sim.core import SimCore

log = logging.getLogger("seaway_sim")

SAVE_EVERY_S = 0.5
"""Simulated seconds between two writes of the plant's state: a restart puts the vessel back where
it was at most this long before the sim stopped (about 0.5 m at 1 m/s)."""

PlantKeptError = atomic.StateFileError


class KeptPlant(ConfigModel):
    """The plant's state as kept (local NED frame of the scenario's origin; body-frame speeds)."""

    scenario: str = Field(description="the scenario's name")
    seed: int = Field(description="the scenario's seed")
    x: list[float] = Field(
        min_length=6, max_length=6, description="[u_mps, v_mps, r_radps, x_m, y_m, psi_rad] of the plant"
    )
    energy_j: float = Field(ge=0, description="propulsion energy used since the scenario started [J]")
    pack_elapsed_ns: int = Field(
        ge=0, description="simulated time the pack's hotel load has drawn for since the scenario started [ns]"
    )
    saved_unix_ns: int = Field(ge=0, description="when it was kept [ns since the Unix epoch]")


def plant_path(state_file: Path) -> Path:
    """Where the plant is kept for a sim whose ``--state-file`` is ``state_file``."""
    return state_file.with_name(f"{state_file.stem}.plant.json")


def snapshot(core: SimCore, now_unix_ns: int) -> KeptPlant:
    """The core's plant now."""
    st = core.plant.state
    return KeptPlant(
        scenario=core.scenario.name,
        seed=core.scenario.seed,
        x=list(st.x),
        energy_j=st.energy_j,
        pack_elapsed_ns=max(core.t_ns - core.pack_since_ns, 0),
        saved_unix_ns=now_unix_ns,
    )


def restore(core: SimCore, kept: KeptPlant) -> None:
    """Put the core's plant where ``kept`` says (the scenario must be the one kept: ``resumable``).
    The samples taken of the start pose are dropped: the next ones describe the kept state."""
    st = core.plant.state
    st.x = list(kept.x)
    st.energy_j = kept.energy_j
    core.pack_since_ns = core.t_ns - kept.pack_elapsed_ns
    core.take_samples()


def resumable(kept: KeptPlant | None, core: SimCore, run_file: str | Path | None) -> str | None:
    """Why ``kept`` is not this sim's to resume (None: it is; also None when nothing was kept)."""
    if kept is None:
        return None
    if from_earlier_launch(kept.saved_unix_ns, run_file):
        return "kept before this run started (an earlier launch into this folder)"
    if (kept.scenario, kept.seed) != (core.scenario.name, core.scenario.seed):
        return (
            f"kept for scenario {kept.scenario} (seed {kept.seed}), this sim flies "
            f"{core.scenario.name} (seed {core.scenario.seed})"
        )
    if not all(math.isfinite(v) for v in (*kept.x, kept.energy_j)):
        return "not finite"
    return None


def load(path: Path) -> KeptPlant | None:
    """What ``path`` keeps; None if there is no file; PlantKeptError if it cannot be used."""
    return atomic.read_model(path, KeptPlant)


class PlantKeeper:
    """Writes the plant's state every ``SAVE_EVERY_S`` of simulated time (``tick``, lock held by
    the caller), off the loop's thread."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._every_ns = round(SAVE_EVERY_S * 1e9)
        self._next_ns = 0
        self._writer = atomic.LatestWriter(path, self._failed, name="sim-plant-writer")

    def _failed(self, err: OSError) -> None:
        log.error(
            "plant state not kept in %s: %s; a restarted sim would start the vessel afresh", self.path, err
        )

    def tick(self, core: SimCore) -> None:
        if core.t_ns < self._next_ns:
            return
        self._next_ns = core.t_ns + self._every_ns
        self._writer.submit(snapshot(core, time.time_ns()).model_dump_json())

    def close(self, core: SimCore) -> None:
        """Keep the plant as it is now, and wait for the write (a clean stop)."""
        self._writer.submit(snapshot(core, time.time_ns()).model_dump_json())
        self._writer.close()
