"""Launcher profiles (``deploy/profiles/*.toml``): which processes a role runs, and how.

A profile is pure data, validated here before anything starts:

* every process names its command (argv; ``{vessel}``, ``{run}`` (the run description file),
  ``{run_dir}``, ``{profile}`` (the profile file), ``{scenario}`` and ``{recording}`` are
  substituted), its restart policy (``never`` or ``on-failure`` with exponential back-off) and
  whether the run fails without it (``required``);
* readiness is the process's Zenoh liveliness token ``seaway/<vessel>/health/<service>``;
* start order follows ``after``; stop order is the reverse, with the recorder always last;
* each key has at most one producer in a profile: by default a process produces the registry keys
  whose producer is its service; ``produces`` overrides that (the lockstep sim produces the sensor
  keys itself). Two producers of one key are refused, naming both;
* what a process must keep publishing, or be restarted as hung, is its service's
  (``liveness.DUTIES``); ``must_publish`` replaces that list (``[]``: only its health token counts).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from seaway.contract import access, keys
from seaway.contract.config import ConfigError, ConfigModel, deploy_path, load_config
from seaway.tools.launch.liveness import Duty, duties_for


class ProcessSpec(ConfigModel):
    name: str = Field(pattern=r"^[a-z][a-z0-9_-]{0,31}$")
    command: list[str] = Field(min_length=1)
    service: str | None = Field(default=None, description="health token name; None: no readiness")
    restart: Literal["never", "on-failure"] = "on-failure"
    required: bool = True
    after: list[str] = Field(default_factory=list)
    produces: list[str] | None = Field(default=None, description="key suffixes; default: registry")
    ready_timeout_s: float = Field(default=30.0, gt=0)
    stop_timeout_s: float = Field(default=3.0, gt=0, description="SIGINT, then SIGKILL after this")
    env: dict[str, str] = Field(default_factory=dict)
    must_publish: list[Duty] | None = Field(default=None, description="what it must keep "
                                            "publishing or be restarted as hung; default: its "
                                            "service's (liveness.DUTIES)")

    @model_validator(mode="after")
    def _service_known(self) -> ProcessSpec:
        if self.service is not None and self.service not in keys.SERVICES:
            raise ValueError(f"service {self.service!r} unknown; known: {', '.join(keys.SERVICES)}")
        return self

    @property
    def identity(self) -> str:
        """Who this process is on the bus (its certificate's name): its service, else its name."""
        return self.service or self.name

    def produced_keys(self) -> list[str]:
        if self.produces is not None:
            return list(self.produces)
        return [s.suffix for s in keys.REGISTRY if s.producer == self.service and s.kind == "topic"]

    def duties(self, clock: str) -> tuple[Duty, ...]:
        """What this process must keep publishing under the run's ``clock``."""
        return duties_for(self.service, clock, self.must_publish)


class BackoffPolicy(ConfigModel):
    initial_s: float = Field(default=0.5, gt=0)
    factor: float = Field(default=2.0, ge=1)
    max_s: float = Field(default=10.0, gt=0)
    max_restarts: int = Field(default=10, ge=0, description="per process, then it counts as failed")

    def delay_s(self, restarts_so_far: int) -> float:
        """Wait before restart number ``restarts_so_far + 1``."""
        return min(self.max_s, self.initial_s * self.factor ** restarts_so_far)


class Profile(ConfigModel):
    name: str
    description: str = ""
    zenoh_config: str | None = Field(default=None, description="path relative to deploy/zenoh")
    side: Literal["local", "boat", "shore"] = Field(
        default="local", description="'local': a stack alone on its machine, with a new authority per "
        "run unless $SEAWAY_CREDENTIALS names one; 'boat'/'shore': one half of a deployment, which "
        "needs the deployment's credentials for that side (seaway credentials create DIR --deployment)")
    scenario: str | None = Field(default=None, description="default scenario name or path")
    clock: Literal["wall", "lockstep"] = Field(default="wall", description="the run's clock: 'wall' "
                                               "(real time) or 'lockstep' (the simulator owns time)")
    vessel_file: str | None = Field(default=None, description="vessel file the services model; "
                                    "default: the scenario's")
    origin_from_scenario: bool = Field(default=True, description="the services share the simulator's "
                                       "NED origin; false on a boat (the first GNSS fix)")
    mode_on_start: str | None = Field(default=None, description="request this autopilot mode when ready")
    arm_on_start: bool = Field(default=False, description="request arming when ready (after the mode)")
    mission_on_start: bool = Field(default=False, description="send the scenario's mission")
    stop_when_complete: bool = Field(default=False, description="stop the run when it completes")
    stop_after: str | None = Field(default=None, description="stop the run when this process exits 0")
    backoff: BackoffPolicy = BackoffPolicy()
    processes: list[ProcessSpec] = Field(min_length=1)

    @model_validator(mode="after")
    def _consistent(self) -> Profile:
        names = [p.name for p in self.processes]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"process names used twice: {', '.join(sorted(dup))}")
        if self.stop_after is not None and self.stop_after not in names:
            raise ValueError(f"stop_after names unknown process {self.stop_after!r}")
        for p in self.processes:
            unknown = [a for a in p.after if a not in names]
            if unknown:
                raise ValueError(f"process {p.name!r}: 'after' names unknown {', '.join(unknown)}")
        producers: dict[str, str] = {}
        registered = {s.suffix for s in keys.REGISTRY}
        for p in self.processes:
            for k in p.produced_keys():
                if k not in registered:
                    raise ValueError(f"process {p.name!r} produces unregistered key {k!r}")
                if k in producers:
                    raise ValueError(f"key {k!r} has two producers: {producers[k]!r} and {p.name!r}; "
                                     "a profile has one producer per key")
                producers[k] = p.name
        for p in self.processes:
            produced = set(p.produced_keys())
            for d in p.duties(self.clock):
                if d.key not in produced:
                    raise ValueError(f"process {p.name!r} must publish {d.key!r} (must_publish), "
                                     "but does not produce it in this profile")
        start_order(self.processes)  # raises on a cycle
        try:
            access.producers(self.producers())
        except access.AccessError as err:
            raise ValueError(str(err)) from None
        return self

    def producers(self) -> dict[str, str]:
        """Each key this profile produces and the identity producing it: the access rules narrow
        every such key to that one process (``contract.access``)."""
        return {k: p.identity for p in self.processes for k in p.produced_keys()}


def start_order(processes: list[ProcessSpec]) -> list[ProcessSpec]:
    """Processes in an order that respects ``after`` (stable otherwise); a cycle is an error."""
    by_name = {p.name: p for p in processes}
    done: list[str] = []
    visiting: set[str] = set()

    def visit(name: str, chain: list[str]) -> None:
        if name in done:
            return
        if name in visiting:
            raise ValueError(f"start order has a cycle: {' -> '.join([*chain, name])}")
        visiting.add(name)
        for dep in by_name[name].after:
            visit(dep, [*chain, name])
        visiting.discard(name)
        done.append(name)

    for p in processes:
        visit(p.name, [])
    return [by_name[n] for n in done]


def stop_order(processes: list[ProcessSpec]) -> list[ProcessSpec]:
    """Reverse start order, recorders last (so they see everything the others say on the way out)."""
    rev = list(reversed(start_order(processes)))
    return [p for p in rev if p.service != "recorder"] + [p for p in rev if p.service == "recorder"]


def load_profile(name_or_path: str | Path) -> Profile:
    p = Path(name_or_path)
    if p.suffix not in (".toml", ".json"):
        p = deploy_path("profiles", f"{name_or_path}.toml")
        if not p.is_file():
            avail = sorted(x.stem for x in p.parent.glob("*.toml"))
            raise ConfigError(f"no profile {name_or_path!r}; available: {', '.join(avail)}")
    return load_config(p, Profile)


def substitute(argv: list[str], values: dict[str, str]) -> list[str]:
    """Replace ``{name}`` placeholders; an unknown placeholder is an error, not a silent literal."""
    out = []
    for a in argv:
        try:
            out.append(a.format(**values))
        except KeyError as err:
            raise ConfigError(f"command argument {a!r} uses unknown placeholder {err}; "
                              f"known: {', '.join(sorted(values))}") from None
    return out
