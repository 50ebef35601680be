"""What a launch that plays a recording (the replay profile) needs to know before anything starts:
whether ``--recording`` fits the profile, and which scenario the recording was made on.

A replay's live estimator and controller are described by the recorded run's scenario (its model,
origin, dead zone) and fly its mission; without one they wait for a mission that never comes. So
the scenario is ``--scenario``, else the one the recorded run's description names (``run.json``
beside the recording), else the launch is refused. (The recorder attaches the same description to
the recording itself; reading it there would take the MCAP reader, ``seaway.recording``, whose
mcap library the launcher's install, ``seaway`` without its ``recording`` extra, does not have.)
"""

from __future__ import annotations

from pathlib import Path

from seaway.contract.config import ConfigError, load_config
from seaway.runtime.run import RunDescription
from seaway.simkit.scenario import load_scenario

RUN_FILE = "run.json"
"""The run description the launcher writes in each vessel's folder, beside its recording."""


def takes_recording(commands: list[list[str]]) -> bool:
    """Whether a profile's commands play a recording (one of them takes ``{recording}``)."""
    return any("{recording}" in arg for command in commands for arg in command)


def recording_problem(profile_name: str, takes: bool, recording: Path | None) -> str | None:
    """What is wrong with ``--recording`` for a profile (None: nothing), said before anything
    starts: a profile that plays one (``takes``, replay) needs one that holds MCAP files; any other
    ignores it, so giving one is a mistake (``sim-batch --recording x`` flew a mission)."""
    if not takes:
        return (
            None
            if recording is None
            else f"--recording: profile {profile_name} plays no recording (the replay profile does)"
        )
    if recording is None:
        return (
            f"profile {profile_name} plays a recording: give it with --recording PATH (a run "
            "folder or an .mcap file)"
        )
    if not recording.exists():
        return f"--recording {recording}: no such file or folder"
    if recording.is_dir() and not any(recording.glob("*.mcap")):
        return f"--recording {recording}: the folder holds no .mcap file"
    if recording.is_file() and recording.suffix != ".mcap":
        return f"--recording {recording}: not an .mcap file"
    return None


def recorded_scenario(recording: Path) -> str:
    """The scenario (name or path) of the run ``recording`` was made in: the one its run
    description names (``run.json`` in the run folder, beside the recording: the launcher writes
    it there, and the recorder attaches the same to the recording), checked to load here.
    ConfigError naming what is missing (no run description, one without a scenario, a scenario not
    found on this machine) and that ``--scenario`` supplies it."""
    folder = recording if recording.is_dir() else recording.parent
    path = folder / RUN_FILE
    if not path.is_file():
        raise ConfigError(
            f"--recording {recording}: no run description ({path}) to name the "
            "scenario it was made on; give the scenario with --scenario"
        )
    try:
        run = load_config(path, RunDescription)
    except ConfigError as err:
        raise ConfigError(
            f"--recording {recording}: {err}; give the scenario it was made on with --scenario"
        ) from None
    if not run.scenario:
        raise ConfigError(
            f"--recording {recording}: its run description ({path}) names no "
            "scenario (a run not simulated by Seaway?); give the scenario with "
            "--scenario"
        )
    try:
        load_scenario(run.scenario)
    except ConfigError as err:
        raise ConfigError(
            f"--recording {recording}: the scenario it was made on, "
            f"{run.scenario!r}, cannot be loaded here ({err}); give it with "
            "--scenario"
        ) from None
    return run.scenario
