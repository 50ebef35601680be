"""The file reference: the fields of every file a user writes (vessel, scenario, mission, operating
area, launcher profile, service configs) and of the run description, with their bounds.

From the pydantic types that read them (each rejects unknown fields), through their JSON Schema.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from seaway_lab.docs_reference.markdown import (
    GENERATED_NOTE,
    cell,
    code,
    constant_docs,
    describe,
    field_table,
    schema_sections,
    table,
)


def _files() -> list[tuple[str, str, type[BaseModel], str]]:
    """(heading, where the files are, type, note) of each kind of file, in the page's order."""
    from seaway.area.spec import AreaSpec
    from seaway.contract.missions import MissionSpec
    from seaway.runtime.run import RunDescription
    from seaway.simkit.scenario import Scenario
    from seaway.tools.launch.profile import Profile
    from seaway.vessel.model import VesselParams
    from seaway_controller.config import ControllerServiceConfig
    from seaway_estimator.config import EstimatorConfig
    from seaway_recorder.config import RecorderConfig
    from seaway_sim.config import SimConfig
    from seaway_vehicle_io.config import VehicleIoConfig

    return [
        ("Vessel file", "deploy/vessels/*.toml", VesselParams, ""),
        ("Scenario", "deploy/scenarios/*.toml", Scenario, "scenario"),
        ("Mission file", "deploy/missions/*.toml, or a scenario's [mission] table", MissionSpec, ""),
        ("Operating area file", "an area's TOML or JSON (also from GeoJSON or a QGroundControl .plan)",
         AreaSpec, ""),
        ("Launcher profile", "deploy/profiles/*.toml", Profile, ""),
        ("vehicle_io config", "services/vehicle_io/config/*.toml", VehicleIoConfig, ""),
        ("Estimator config", "services/estimator/config/*.toml", EstimatorConfig, ""),
        ("Controller config", "seaway-controller --config FILE", ControllerServiceConfig, ""),
        ("Simulator config", "seaway-sim --config FILE", SimConfig, ""),
        ("Recorder config", "seaway-recorder --config FILE", RecorderConfig, ""),
        ("Run description", "runs/<run>/run.json (written by the launcher)", RunDescription, ""),
    ]


def _scenario_limits() -> str:
    """The scenario module's MAX_* bounds, with the comment or docstring that says why."""
    from seaway.contract.messages import sensors
    from seaway.simkit import scenario
    from seaway.vessel import frames

    # A limit defined where its name belongs (the sensors', the local frame's) says why there.
    docs = {**constant_docs(frames), **constant_docs(sensors), **constant_docs(scenario)}
    rows = [[code(name), code(f"{getattr(scenario, name):g}"), cell(describe(docs.get(name, "")))]
            for name in sorted(vars(scenario)) if name.startswith("MAX_")
            and isinstance(getattr(scenario, name), int | float)]
    return ("Disturbances and the start are bounded to what every vessel file's plant survives "
            "(`seaway.simkit.scenario`):\n\n" + table(["limit", "value", "why"], rows) + "\n")


def section(heading: str, where: str, model: type[BaseModel], note: str) -> str:
    schema: dict[str, Any] = model.model_json_schema()
    return "".join([
        f"## {heading}\n\n",
        f"`{where}`, read as `{model.__module__}.{model.__name__}`: {describe(model.__doc__)}\n\n",
        field_table(schema), "\n",
        _scenario_limits() if note == "scenario" else "",
        schema_sections(schema, level=3),
    ])


def page() -> str:
    """``docs/reference/files.md``."""
    return "".join([
        GENERATED_NOTE, "# Files\n\n",
        "The fields of each file Seaway reads, with their defaults and bounds. Files are TOML or "
        "JSON; unknown fields are refused, and every error names the file and the field.\n\n",
        *(section(*f) for f in _files()),
    ])
