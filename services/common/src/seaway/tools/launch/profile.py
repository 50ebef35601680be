"""Launcher profiles (``deploy/profiles/*.toml``): which processes a role runs, and how.

A profile is pure data, validated here before anything starts:

* every process names its command (argv; ``{vessel}``, ``{run}`` (the run description file),
  ``{run_dir}``, ``{profile}`` (the profile file), ``{scenario}`` and ``{recording}`` are
  substituted), its restart policy (``never`` or ``on-failure`` with exponential back-off) and
  whether the run fails without it (``required``);
* readiness is the process's Zenoh liveliness token ``seaway/<vessel>/health/<service>``;
* a process starts once every process it names in ``after`` is ready (those with nothing between
  them start together); stop order is the reverse of ``after``, with the recorder always last;
* each key has at most one producer in a profile: by default a process produces the registry keys
  whose producer is its service; ``produces`` overrides that (the lockstep sim produces the sensor
  keys itself). Two producers of one key are refused, naming both;
* what a process must keep publishing, or be restarted as hung, is its service's
  (``liveness.DUTIES``); ``must_publish`` replaces that list (``[]``: only its health token counts).

**Several vessels** (a fleet, ``deploy/profiles/fleet.toml``): ``vessels`` lists them, and each
process marked ``per_vessel`` runs once per vessel (``instances``): named ``<name>-<vessel>``, with
that vessel's ``{vessel}``, ``{run}`` (its own run description), ``{vessel_dir}`` (its folder in
the run folder), ``{mavlink_port}`` (a UDP port of its own) and ``{vessel_index}`` (its place in
the list, from 0: the fleet's simulators start side by side by it); its ``after`` names the same
vessel's copies. A process not marked runs once for the launch, on its first vessel (``{vessel}``,
``{run}`` are the first vessel's; ``{vessel_dir}`` is the run folder), after every copy of what it
names in ``after``. One producer per key holds per vessel: the copies produce the same keys, each
under its own ``seaway/<vessel>/``. A launch of one vessel runs every process once, under its own
name, whether it is marked or not.
"""

from __future__ import annotations

import math
import string
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from seaway.contract import access, keys
from seaway.contract.config import ConfigError, ConfigModel, deploy_path, load_config
from seaway.ros2.face import WRITES_FLAG
from seaway.runtime.lockstep import MEMBERS
from seaway.tools.launch.liveness import Duty, duties_for

DEFAULT_READY_TIMEOUT_S = 30.0
"""How long a process may take from its start (or restart) to its health token [s] unless its
profile says otherwise (``ProcessSpec.ready_timeout_s``)."""


class ProcessSpec(ConfigModel):
    name: str = Field(pattern=r"^[a-z][a-z0-9_-]{0,31}$")
    command: list[str] = Field(min_length=1)
    service: str | None = Field(default=None, description="health token name; None: no readiness")
    restart: Literal["never", "on-failure"] = "on-failure"
    required: bool = True
    after: list[str] = Field(default_factory=list)
    produces: list[str] | None = Field(default=None, description="key suffixes; default: registry")
    ready_timeout_s: float = Field(default=DEFAULT_READY_TIMEOUT_S, gt=0)
    stop_timeout_s: float = Field(default=3.0, gt=0, description="SIGINT, then SIGKILL after this")
    env: dict[str, str] = Field(default_factory=dict)
    must_publish: list[Duty] | None = Field(default=None, description="what it must keep "
                                            "publishing or be restarted as hung; default: its "
                                            "service's (liveness.DUTIES)")
    per_vessel: bool = Field(default=False, description="one copy per vessel of the launch "
                             "(<name>-<vessel>); else one process for the launch, on its first vessel")

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
    """How long the supervisor waits before restarting a failed process: ``initial_s``, times
    ``factor`` at each restart, at most ``max_s``; ``max_restarts`` restarts of a process at most.

    Every field is bounded, and ``delay_s`` never computes a power past ``max_s``, so that the
    delay is a finite float for any restart count (``factor ** n`` overflows a float: the default
    factor 2 at n = 1025)."""

    initial_s: float = Field(default=0.5, ge=0.001, le=3600.0, description="the first wait [s]; at "
                             "least 1 ms (sooner is a busy loop), at most an hour")
    factor: float = Field(default=2.0, ge=1, le=10.0, description="each wait is this many times the "
                          "last; at most 10 (more reaches max_s in a restart or two all the same)")
    max_s: float = Field(default=10.0, gt=0, le=3600.0, description="the longest wait [s]; at most "
                         "an hour (a restart later than that is one nobody waits for)")
    max_restarts: int = Field(default=10, ge=0, le=1000, description="per process, then it counts as "
                              "failed; at most 1000 (hours of a process failing at max_s 10 s)")

    def delay_s(self, restarts_so_far: int) -> float:
        """Wait before restart number ``restarts_so_far + 1`` [s]."""
        # Compared as logarithms: once initial_s * factor**n would pass max_s the power is never
        # computed, so no restart count overflows it. Below that, factor**n < max_s / initial_s,
        # at most 3.6e6 within the bounds.
        grown = restarts_so_far * math.log(self.factor)
        if grown >= math.log(self.max_s) - math.log(self.initial_s):
            return self.max_s
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
    tiles: str | None = Field(default=None, description="the ground station's map tiles (launch "
                              "--tiles overrides): an http(s) {z}/{x}/{y} URL template, a folder "
                              "<z>/<x>/<y>.png or an .mbtiles file; none: the metric grid")
    clock: Literal["wall", "lockstep"] = Field(default="wall", description="the run's clock: 'wall' "
                                               "(real time) or 'lockstep' (the simulator owns time)")
    vessel_file: str | None = Field(default=None, description="vessel file the services model; "
                                    "default: the scenario's")
    origin_from_scenario: bool = Field(default=True, description="the services share the simulator's "
                                       "NED origin; false on a boat (the first GNSS fix)")
    mode_on_start: str | None = Field(default=None, description="request this autopilot mode when ready")
    arm_on_start: bool = Field(default=False, description="request arming when ready (after the mode)")
    arm_wait_s: float = Field(default=0.0, ge=0, le=600, description="while the autopilot refuses to "
                              "arm, ask again every few seconds for this long (an autopilot whose "
                              "position estimate is still converging: ArduPilot ~40 s after boot); "
                              "0: one request")
    mission_on_start: bool = Field(default=False, description="send the scenario's mission")
    stop_when_complete: bool = Field(default=False, description="stop the run when it completes")
    stop_after: str | None = Field(default=None, description="stop the run when this process exits 0")
    vessels: list[str] | None = Field(default=None, min_length=1, description="a fleet: the "
                                      "vessels it runs, each with its own copy of every per_vessel "
                                      "process (launch --vessels replaces the list); None: the one "
                                      "vessel of launch --vessel")
    backoff: BackoffPolicy = BackoffPolicy()
    processes: list[ProcessSpec] = Field(min_length=1)

    @model_validator(mode="after")
    def _consistent(self) -> Profile:
        if self.vessels is not None:
            check_vessels(self.vessels, self.clock)
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
            if self.clock == "lockstep" and not p.required and p.service in MEMBERS:
                # The clock waits for every member each period: one that failed for good would
                # hold simulated time for ever while the launcher waited for the run to end.
                raise ValueError(f"process {p.name!r} is a lockstep member ({p.service}): in a "
                                 "lockstep profile it must be required (required = true)")
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

    def ros2_writes(self) -> bool:
        """Whether a ROS 2 face of this profile takes requests from ROS 2 (``--ros2-writes``): its
        stack's access rules must then let it ask them (``contract.access.ROS2_REQUESTS``)."""
        return any(p.service == ROS2_PROCESS and WRITES_FLAG in p.command for p in self.processes)

    def producers(self) -> dict[str, str]:
        """Each key this profile produces and the identity producing it: the access rules narrow
        every such key to that one process (``contract.access``)."""
        return {k: p.identity for p in self.processes for k in p.produced_keys()}


def check_vessels(vessels: list[str], clock: str) -> list[str]:
    """``vessels`` if they can run as one launch: valid key names, each once; several only in real
    time (a lockstep simulator steps one vessel's stack). ValueError naming the problem."""
    for v in vessels:
        keys.check_vessel(v)
    dup = sorted({v for v in vessels if vessels.count(v) > 1})
    if dup:
        raise ValueError(f"vessels listed twice: {', '.join(dup)}")
    if len(vessels) > 1 and clock != "wall":
        raise ValueError(f"{len(vessels)} vessels with clock {clock!r}: a lockstep run has one "
                         "vessel (its simulator steps that vessel's stack); a fleet runs in real "
                         "time (clock 'wall')")
    return vessels


@dataclass(frozen=True)
class Instance:
    """One process of a launch: its spec (named as the launch names it, ``after`` naming instances)
    and the vessel it runs for (a process for the whole launch: the launch's first vessel)."""

    spec: ProcessSpec
    vessel: str
    per_vessel: bool
    """One of the copies of a ``per_vessel`` process in a launch of several vessels."""


def instance_name(name: str, vessel: str) -> str:
    """What a launch of several vessels calls ``vessel``'s copy of the per-vessel process ``name``."""
    return f"{name}-{vessel}"


def instances(profile: Profile, vessels: list[str]) -> list[Instance]:
    """The processes a launch of ``profile`` for ``vessels`` runs (module docstring), in the
    profile's order, each per-vessel process's copies in the order of ``vessels``. ConfigError if
    the vessels cannot run together or two instances would share a name."""
    try:
        check_vessels(vessels, profile.clock)
    except ValueError as err:
        raise ConfigError(f"profile {profile.name}: {err}") from None
    if len(vessels) == 1:
        return [Instance(p, vessels[0], False) for p in profile.processes]
    per = {p.name for p in profile.processes if p.per_vessel}
    if profile.stop_after in per:
        raise ConfigError(f"profile {profile.name}: stop_after names {profile.stop_after!r}, which "
                          f"runs once per vessel; with {len(vessels)} vessels it must name a "
                          "process of the whole launch")
    out: list[Instance] = []
    for p in profile.processes:
        if p.per_vessel:
            for v in vessels:
                after = [instance_name(a, v) if a in per else a for a in p.after]
                out.append(Instance(p.model_copy(update={"name": instance_name(p.name, v),
                                                         "after": after}), v, True))
        else:
            after = [n for a in p.after
                     for n in ([instance_name(a, v) for v in vessels] if a in per else [a])]
            out.append(Instance(p.model_copy(update={"after": after}), vessels[0], False))
    names = [i.spec.name for i in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigError(f"profile {profile.name}: with vessels {', '.join(vessels)} two processes "
                          f"would be named {', '.join(dup)}; rename the process")
    return out


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
    """Replace ``{name}`` placeholders (``{{`` and ``}}`` are literal braces). ConfigError naming
    the argument: an unknown placeholder is an error, not a silent literal, and so is anything else
    in braces.

    Only a bare known name is substituted: ``str.format``'s positional fields (``{0}``), attributes
    (``{vessel.zz}``), format specs and conversions mean nothing in an argv."""
    known = ", ".join(sorted(values))
    out = []
    for a in argv:
        try:
            fields = [(name, spec, conversion)
                      for _, name, spec, conversion in string.Formatter().parse(a) if name is not None]
        except ValueError as err:  # a lone { or }
            raise ConfigError(f"command argument {a!r}: {err}; a placeholder is a name in braces "
                              "({vessel}), a literal brace is written {{ or }}") from None
        for name, spec, conversion in fields:
            if name not in values:
                hint = "" if name.isidentifier() else " (a placeholder is a bare name in braces)"
                raise ConfigError(f"command argument {a!r} uses unknown placeholder {name!r}{hint}; "
                                  f"known: {known}")
            if spec or conversion:
                raise ConfigError(f"command argument {a!r}: placeholder {name!r} has a format spec "
                                  "or conversion (':' or '!'); a placeholder is a bare name in braces")
        out.append(a.format(**values))
    return out


ROS2_PROCESS = "ros2"
"""The name of the ROS 2 face's process a launch adds (``seaway launch --ros2``)."""


def with_ros2(profile: Profile, connect: list[str], domain: int | None = None,
              writes: bool = False) -> Profile:
    """``profile`` with the ROS 2 face (``seaway-ros2``, docs/ros2.md) added, one per vessel,
    connecting to ``connect`` (rmw_zenohd's endpoints) on ROS domain ``domain`` (None: the
    process's ``$ROS_DOMAIN_ID`` or 0); ``writes``: it takes a mission and its pause/resume/abort
    from ROS 2 (``seaway.ros2.writes``). Not required: the vessel does not depend on it. A profile
    that runs it already is refused (one producer of its topics)."""
    if any(p.service == ROS2_PROCESS for p in profile.processes):
        raise ConfigError(f"profile {profile.name} runs the ROS 2 face already; leave --ros2 out")
    command = ["seaway-ros2", "--vessel", "{vessel}", "--run", "{run}"]
    for endpoint in connect:
        command += ["--ros2-connect", endpoint]
    if domain is not None:
        command += ["--ros2-domain", str(domain)]
    if writes:
        command.append(WRITES_FLAG)
    spec = {"name": ROS2_PROCESS, "service": ROS2_PROCESS, "required": False, "per_vessel": True,
            "command": command}
    data = profile.model_dump(exclude_unset=True)
    data["processes"] = [*data["processes"], spec]
    return Profile.model_validate(data)
