"""The one registry of Seaway's key expressions: each key with its message type and producer.

Keys say what the data is, not who made it (design.md): the sim, a real vessel or a replay can each
produce ``seaway/<vessel>/sensors/gnss``; a launcher profile has exactly one producer per key. The
``producer`` here is the service that produces the key in a normal run.

Kinds:
* ``topic``: publish/subscribe of ``message`` values;
* ``query``: a queryable taking ``message`` as its request and answering ``Reply``;
* ``liveliness``: a Zenoh liveliness token (no payload), ``health/<service>``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

from seaway.contract import messages as m

ROOT = "seaway"
SERVICES = ("sim", "vehicle_io", "estimator", "controller", "groundstation", "recorder", "launcher",
            "router", "ros2")

# A vessel name is one key chunk: no wildcards, separators or verbatim markers.
_VESSEL_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class KeyNameError(ValueError):
    """A vessel or service name that cannot form a valid key expression."""


@dataclass(frozen=True)
class KeySpec:
    """One registered key: ``seaway/<vessel>/<suffix>``."""

    suffix: str
    message: type[m.Message] | None
    producer: str
    kind: Literal["topic", "query", "liveliness"] = "topic"
    doc: str = ""
    also: tuple[str, ...] = ()
    """Other services that may stand in for ``producer`` in some profile (the sim or a replay
    producing the sensor keys); a profile narrows each key to exactly one (``contract.access``)."""

    @property
    def producers(self) -> tuple[str, ...]:
        """Every identity that may produce this key in some profile: ``producer`` first."""
        return (self.producer, *self.also)

    def key(self, vessel: str) -> str:
        """The concrete key expression for one vessel."""
        return f"{ROOT}/{check_vessel(vessel)}/{self.suffix}"

    def wildcard(self) -> str:
        """The key expression matching this key on every vessel."""
        return f"{ROOT}/*/{self.suffix}"


def check_vessel(vessel: str) -> str:
    if not _VESSEL_RE.match(vessel):
        raise KeyNameError(
            f"vessel name {vessel!r} is not valid: use 1-64 letters, digits, '_', '.' or '-', "
            "starting with a letter or digit"
        )
    return vessel


# The sensors come from vehicle_io on a real or MAVLink-simulated vessel; the lockstep sim and a
# replay publish them themselves.
SENSOR_STAND_INS = ("sim", "replay")
GNSS = KeySpec("sensors/gnss", m.GnssFix, "vehicle_io", doc="GNSS fix", also=SENSOR_STAND_INS)
ATTITUDE = KeySpec("sensors/attitude", m.Attitude, "vehicle_io", doc="attitude and rates",
                   also=SENSOR_STAND_INS)
LOCAL_POSITION = KeySpec("sensors/local_position", m.LocalPosition, "vehicle_io",
                         also=SENSOR_STAND_INS)
VEHICLE_STATUS = KeySpec("vehicle/status", m.VehicleStatus, "vehicle_io")
VEHICLE_BATTERY = KeySpec("vehicle/battery", m.BatteryState, "vehicle_io",
                          doc="the propulsion battery in SI units", also=SENSOR_STAND_INS)
VEHICLE_ARM = KeySpec("vehicle/arm", m.ArmRequest, "vehicle_io", "query")
VEHICLE_MODE = KeySpec("vehicle/mode", m.ModeRequest, "vehicle_io", "query")
NAV_STATE = KeySpec("nav/state", m.StateEstimate, "estimator")
NAV_ORIGIN = KeySpec("nav/origin", m.NavOrigin, "estimator")
NAV_RESET = KeySpec("nav/reset", m.NavResetRequest, "estimator", "query", doc="re-initialise")
THRUST = KeySpec("ctrl/thrust", m.ThrustCommand, "controller")
SOLVE = KeySpec("ctrl/solve", m.SolveRecord, "controller")
MISSION_STATUS = KeySpec("mission/status", m.MissionStatus, "controller")
MISSION_ACCEPTED = KeySpec("mission/accepted", m.MissionAccepted, "controller",
                            doc="the mission accepted, in local NED: on acceptance, and 1 Hz live")
MISSION_ENERGY = KeySpec("mission/energy", m.EnergyBudget, "controller",
                         doc="energy to finish and to get home against the battery; the decision: "
                             "1 Hz and at each new leg of an active mission")
AREA_ACTIVE = KeySpec("area/active", m.ActiveArea, "controller",
                     doc="the operating area the controller enforces, in local NED: when it comes "
                         "into force, and 1 Hz live")
MISSION_SET = KeySpec("mission/set", m.MissionRequest, "controller", "query")
MISSION_COMMAND = KeySpec("mission/command", m.MissionCommand, "controller", "query")
MISSION_HOME = KeySpec("mission/home", m.HomeRequest, "controller", "query",
                       doc="set the vessel's home (the operator's; else where it was armed)")
SIM_TRUTH = KeySpec("sim/truth", m.SimTruth, "sim", also=("replay",))
SIM_DISTURBANCE = KeySpec("sim/disturbance", m.DisturbanceForce, "sim", also=("replay",))
SIM_CLOCK = KeySpec("sim/clock", m.ClockTick, "sim", also=("replay",))
SIM_SCENARIO = KeySpec("sim/scenario", m.ScenarioRequest, "sim", "query")
LOCKSTEP_SIM = KeySpec("lockstep/sim", m.PeriodDone, "sim", doc="lockstep: the period's tick",
                      also=("replay",))
LOCKSTEP_ESTIMATOR = KeySpec("lockstep/estimator", m.PeriodDone, "estimator")
LOCKSTEP_CONTROLLER = KeySpec("lockstep/controller", m.PeriodDone, "controller")
LOCKSTEP_RECORDER = KeySpec("lockstep/recorder", m.PeriodDone, "recorder")
LOG_LINE = KeySpec("logs/line", m.LogRecord, "recorder",
                   doc="each line of the run's process logs, as the recorder tails them")

REGISTRY: tuple[KeySpec, ...] = tuple(v for v in list(globals().values()) if isinstance(v, KeySpec))
"""Every key defined above, in that order: defining a ``KeySpec`` here registers it."""
_BY_SUFFIX: dict[str, KeySpec] = {spec.suffix: spec for spec in REGISTRY}
if len(_BY_SUFFIX) != len(REGISTRY):
    raise RuntimeError("a key suffix is registered twice")  # two names for one key: one place each


HEALTH = "health"
"""``seaway/<vessel>/health/<service>``: liveliness tokens, one per ready service."""
RUN = "run"
"""``seaway/<vessel>/run/<service>``: each service's run description (a queryable)."""
REFUSALS = "refusals"
"""``seaway/<vessel>/refusals/<identity>``: what one process's access control refused (a queryable
answering, and a topic published on change, ``Refusals``)."""


SHORE_HEALTH_PREFIX = "shore-"
"""A shore process's health token is ``health/shore-<service>`` (``side_service``): the shore also
hears the boat's ``health/<service>`` through its router, and the two must not stand for each other
(the boat's recorder dead while the shore's lives on the same key, unseen)."""


def side_service(service: str, side: str) -> str:
    """The name in the health token of ``service`` run on ``side`` (``seaway.contract.access.SIDES``:
    ``local``, ``boat`` or ``shore``)."""
    return SHORE_HEALTH_PREFIX + service if side == "shore" else service


def own_service(token: str, side: str) -> str | None:
    """The service a health token's name stands for when the token is ``side``'s own, else None
    (on a shore, the boat's tokens its router brings)."""
    if side != "shore":
        return token
    return token[len(SHORE_HEALTH_PREFIX):] if token.startswith(SHORE_HEALTH_PREFIX) else None


def health_key(vessel: str, service: str, side: str = "local") -> str:
    """Liveliness token key of one service on one vessel, run on ``side`` (``side_service``)."""
    if service not in SERVICES:
        raise KeyNameError(f"unknown service {service!r}; known: {', '.join(SERVICES)}")
    return f"{ROOT}/{check_vessel(vessel)}/{HEALTH}/{side_service(service, side)}"


def vessel_wildcard(vessel: str | None = None) -> str:
    """Every key of one vessel (``seaway/<vessel>/**``), or of every vessel (``seaway/**``)."""
    return f"{ROOT}/**" if vessel is None else f"{ROOT}/{vessel}/**"


def health_wildcard(vessel: str = "*") -> str:
    return f"{ROOT}/{vessel}/{HEALTH}/*"


def run_description_key(vessel: str, service: str) -> str:
    """Where one service answers with its run description (``seaway.runtime.run``)."""
    if service not in SERVICES:
        raise KeyNameError(f"unknown service {service!r}; known: {', '.join(SERVICES)}")
    return f"{ROOT}/{check_vessel(vessel)}/{RUN}/{service}"


def run_description_wildcard(vessel: str) -> str:
    """Every service's run description on one vessel."""
    return f"{ROOT}/{check_vessel(vessel)}/{RUN}/*"


def refusals_key(vessel: str, identity: str) -> str:
    """Where one process reports what its access control refused (``seaway.runtime.refusals``)."""
    return f"{ROOT}/{check_vessel(vessel)}/{REFUSALS}/{check_vessel(identity)}"


def refusals_identity(key: str) -> str | None:
    """The identity a concrete ``seaway/<vessel>/refusals/<identity>`` key reports, else None."""
    parts = key.split("/")
    if len(parts) == 4 and parts[0] == ROOT and parts[2] == REFUSALS and _VESSEL_RE.match(parts[3]):
        return parts[3]
    return None


def refusals_wildcard(vessel: str) -> str:
    """Every process's refusal report on one vessel."""
    return f"{ROOT}/{check_vessel(vessel)}/{REFUSALS}/*"


def lockstep_spec(service: str) -> KeySpec:
    """``lockstep/<service>``: where a lockstep member answers each period (``PeriodDone``)."""
    spec = _BY_SUFFIX.get(f"lockstep/{service}")
    if spec is None:
        raise KeyNameError(f"{service!r} takes no part in lockstep; "
                           f"members: {', '.join(m.LOCKSTEP_SERVICES)}")
    return spec


def spec_for_suffix(suffix: str) -> KeySpec | None:
    """The registered spec of a suffix (``nav/state``), or None."""
    return _BY_SUFFIX.get(suffix)


def spec_for_key(key: str) -> KeySpec | None:
    """The registered spec a concrete key belongs to (``seaway/<vessel>/<suffix>``), or None."""
    parts = key.split("/", 2)
    if len(parts) != 3 or parts[0] != ROOT:
        return None
    return spec_for_suffix(parts[2])
