"""What a launch that plays a recording (the replay profile) needs to know before anything starts:
whether ``--recording`` fits the profile, and which scenario the recording was made on.

A replay's live estimator and controller are described by the recorded run's scenario (its model,
origin, dead zone) and fly its mission; without one they wait for a mission that never comes. So
the scenario is ``--scenario``, else the one the recording's run description names
(``run/run.json``, attached by the recorder to every recording), else the launch is refused.
"""

from __future__ import annotations

from pathlib import Path

from seaway.contract.config import ConfigError
from seaway.simkit.scenario import load_scenario


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
    """The scenario (name or path) the run description attached to ``recording`` names, checked to
    load here. ConfigError naming what is missing (no run description, one without a scenario, a
    scenario not found on this machine) and that ``--scenario`` supplies it."""
    try:  # the recorder package reads MCAP; the replay profile runs its ``seaway replay`` anyway
        from seaway_recorder import recording as recordings
        from seaway_recorder import runinfo
    except ImportError:
        raise ConfigError(
            f"--recording {recording}: reading its scenario needs the seaway-recorder "
            "package; give the scenario with --scenario NAME"
        ) from None
    try:
        run = runinfo.run_from_attachments(
            recordings.read_info(recordings.open_paths([recording])).attachments
        )
    except (OSError, ValueError) as err:  # ConfigError is a ValueError: a bad run.json says so
        raise ConfigError(
            f"--recording {recording}: {err}; give the scenario it was made on with --scenario"
        ) from None
    if run is None:
        raise ConfigError(
            f"--recording {recording}: it holds no run description "
            f"({runinfo.RUN_ATTACHMENT}) to name its scenario; give the scenario it "
            "was made on with --scenario"
        )
    if not run.scenario:
        raise ConfigError(
            f"--recording {recording}: its run description names no scenario (a run "
            "not simulated by Seaway?); give the scenario with --scenario"
        )
    try:
        load_scenario(run.scenario)
    except ConfigError as err:
        raise ConfigError(
            f"--recording {recording}: the scenario it was made on, {run.scenario!r}, "
            f"cannot be loaded here ({err}); give it with --scenario"
        ) from None
    return run.scenario
