"""Foxglove channels derived from bus messages: decoded messages in, Foxglove messages out.

Pure: no file, no bus, no clock. ``FoxgloveDeriver.feed(key, message)`` returns the ``Derived``
messages one decoded bus message gives; ``log_message`` makes a ``foxglove.Log``. Each ``Derived``
carries a ``foxglove.messages`` object from ``foxglove-sdk``, whose schema (``get_schema()``:
``foxglove.<Name>``, protobuf, the SDK's own file descriptor set) and encoding (``encode()``) are
the SDK's, so no copy of a Foxglove schema is written here. ``channel_spec`` is the MCAP channel
for one; ``payload`` its bytes. The recorder writes them to the file (``core.py``); a live
server can log them on the same topics.

Topics, per vessel ``<v>`` (frames: ``map`` is east-north-up for the 3D panel; ``<v>/ned`` the
vessel's local NED at its origin, ``<v>/body`` its body (forward-right-down) from ``nav/state``,
``<v>/truth`` the simulated vessel from ``sim/truth``):

=================================  ===========================  ==============================
topic                              schema                       from
=================================  ===========================  ==============================
``foxglove/<v>/sim-truth``         ``foxglove.LocationFix``     ``sim/truth`` (through the origin)
``foxglove/<v>/nav-state``         ``foxglove.LocationFix``     ``nav/state``, covariance known
``foxglove/<v>/sensors-gnss``      ``foxglove.LocationFix``     ``sensors/gnss``, diagonal
``foxglove/<v>/mission``           ``foxglove.GeoJSON``         ``mission/accepted``: path, circles
``foxglove/<v>/tf/ned``            ``foxglove.FrameTransform``  ``map`` -> ``<v>/ned``, once
``foxglove/<v>/tf/body``           ``foxglove.FrameTransform``  ``<v>/ned`` -> ``<v>/body``
``foxglove/<v>/tf/truth``          ``foxglove.FrameTransform``  ``<v>/ned`` -> ``<v>/truth``
``foxglove/<v>/scene/mission``     ``foxglove.SceneUpdate``     ``mission/accepted``
``foxglove/<v>/scene/vessel``      ``foxglove.SceneUpdate``     the hull on ``<v>/body``, once
``foxglove/<v>/scene/truth``       ``foxglove.SceneUpdate``     the true hull on ``<v>/truth``, once
``foxglove/<v>/scene/prediction``  ``foxglove.SceneUpdate``     ``ctrl/solve``: the MPC's plan
``foxglove/log``                   ``foxglove.Log``             the run's log files
=================================  ===========================  ==============================

What changes rarely has a topic of its own, sent when it changes: Foxglove restores, on a seek,
the latest message of each topic before the new time, so the mission and the hull stay drawn
wherever the user seeks, without being sent again and again.

Timestamps: every derived message's own ``timestamp`` is ``timestamp_ns(source stamp_ns)``, the
function given (``timebase.RecordingTime.foxglove_ns``: the source's stamp in real time, the epoch
plus the sim stamp in lockstep), so it is the same instant as the message's log time.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import foxglove.messages as fg
from seaway.contract import keys
from seaway.contract.messages import (
    GnssFix,
    Message,
    MissionAccepted,
    NavOrigin,
    SimTruth,
    SolveRecord,
    StateEstimate,
)
from seaway.contract.units import NS_PER_S
from seaway.vessel.frames import GeoOrigin

from seaway_recorder.schemas import ChannelSpec

FOXGLOVE_ROOT = "foxglove"
LOG_TOPIC = f"{FOXGLOVE_ROOT}/log"
PROTOBUF = "protobuf"
MAP_FRAME = "map"
"""The 3D panel's display frame: east-north-up (z up), at the vessels' NED origin."""
CIRCLE_VERTICES = 48
"""Vertices of a drawn circle of acceptance (a 1 m circle is then off by at most 2 mm)."""
HULL_M = (1.0, 0.4, 0.2)
"""The drawn hull's length, beam and height [m]: a marker, not the vessel's shape (vessel files
have no hull dimensions)."""

# NED -> ENU is a rotation by 180 degrees about the axis (1, 1, 0)/sqrt(2): x north -> y north,
# y east -> x east, z down -> z up. As a quaternion (x, y, z, w):
_NED_IN_ENU = (math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0)

_COLOR = {
    "path": (0.10, 0.45, 0.85, 1.0), "circle": (0.95, 0.55, 0.10, 0.9),
    "prediction": (0.85, 0.10, 0.55, 1.0), "hull": (0.15, 0.65, 0.30, 0.9),
    "truth": (0.55, 0.55, 0.55, 0.45), "text": (1.0, 1.0, 1.0, 1.0),
}


@dataclass(frozen=True)
class Derived:
    """One derived Foxglove message: its topic, the ``foxglove.messages`` object and the key it
    was derived from ('' for a log line)."""

    topic: str
    message: Any
    source: str = ""

    def payload(self) -> bytes:
        """The message's bytes (protobuf, the SDK's encoding)."""
        return bytes(self.message.encode())


_SPECS: dict[tuple[str, str, str], ChannelSpec] = {}


def channel_spec(d: Derived) -> ChannelSpec:
    """The MCAP channel of a derived message: the SDK's schema (protobuf), ``protobuf`` messages."""
    cache_key = (d.topic, type(d.message).__name__, d.source)
    spec = _SPECS.get(cache_key)
    if spec is None:
        schema = type(d.message).get_schema()
        meta = {"role": "foxglove"}
        if d.source:
            meta["derived_from"] = d.source
        spec = ChannelSpec(d.topic, schema.name, schema.encoding, bytes(schema.data), PROTOBUF,
                           None, meta)
        _SPECS[cache_key] = spec
    return spec


def timestamp(t_ns: int) -> fg.Timestamp:
    return fg.Timestamp(sec=t_ns // NS_PER_S, nsec=t_ns % NS_PER_S)


def _color(name: str) -> fg.Color:
    color = _COLORS.get(name)
    if color is None:
        r, g, b, a = _COLOR[name]
        color = _COLORS[name] = fg.Color(r=r, g=g, b=b, a=a)
    return color


_COLORS: dict[str, fg.Color] = {}
"""Each color made once: a message holds its parts by value (``encode`` writes what they are)."""


def _yaw(psi_rad: float) -> fg.Quaternion:
    """Heading psi (clockwise from north) as a rotation about NED's z (down)."""
    return fg.Quaternion(x=0.0, y=0.0, z=math.sin(psi_rad / 2), w=math.cos(psi_rad / 2))


def _identity_pose() -> fg.Pose:
    return _IDENTITY_POSE


_IDENTITY_POSE = fg.Pose(position=fg.Vector3(x=0.0, y=0.0, z=0.0),
                         orientation=fg.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))


def circle_ned(x_m: float, y_m: float, r_m: float, n: int = CIRCLE_VERTICES) -> list[tuple[float, float]]:
    """``n`` points of the circle of radius ``r_m`` around (x_m, y_m), NED metres."""
    return [(x_m + r_m * math.cos(2 * math.pi * k / n), y_m + r_m * math.sin(2 * math.pi * k / n))
            for k in range(n)]


def location_fix(t_ns: int, frame_id: str, lat_rad: float, lon_rad: float, alt_m: float, *,
                 heading_rad: float | None = None, enu_covariance_m2: list[float] | None = None,
                 covariance_type: fg.LocationFixPositionCovarianceType =
                 fg.LocationFixPositionCovarianceType.Unknown) -> fg.LocationFix:
    """A ``foxglove.LocationFix`` (degrees; covariance east-north-up, row-major, m^2)."""
    return fg.LocationFix(
        timestamp=timestamp(t_ns), frame_id=frame_id, latitude=math.degrees(lat_rad),
        longitude=math.degrees(lon_rad), altitude=alt_m,
        position_covariance=enu_covariance_m2 if enu_covariance_m2 is not None else [0.0] * 9,
        position_covariance_type=covariance_type, heading=heading_rad)


def enu_position_covariance(state: StateEstimate) -> list[float] | None:
    """The estimate's horizontal position covariance as LocationFix wants it (east-north-up,
    row-major, m^2); None if the estimate carries none. Up is not estimated (a surface vessel):
    its variance is 0."""
    p = state.covariance
    if p is None:
        return None
    xx, xy, yy = p[3 * 9 + 3], p[3 * 9 + 4], p[4 * 9 + 4]  # x north, y east (StateEstimate order)
    return [yy, xy, 0.0, xy, xx, 0.0, 0.0, 0.0, 0.0]


def mission_geojson(msg: MissionAccepted, origin: GeoOrigin) -> str:
    """The accepted mission for the Map panel: the path (a LineString) and each circle of
    acceptance (a Polygon), in degrees (GeoJSON's [longitude, latitude]); ``properties.style`` is
    the Map panel's own styling hook."""

    def lonlat(x: float, y: float) -> list[float]:
        lat, lon, _ = origin.to_geodetic(x, y, 0.0)
        return [math.degrees(lon), math.degrees(lat)]

    pts = msg.waypoints_m()
    label = msg.mission_id or "mission"
    features: list[dict[str, Any]] = [{
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": [lonlat(x, y) for x, y in pts]},
        "properties": {"name": f"{label}: path ({msg.controller})",
                       "style": {"color": "#1f73d9", "weight": 3, "opacity": 0.9}},
    }]
    for i, (x, y) in enumerate(pts):
        ring = [lonlat(a, b) for a, b in circle_ned(x, y, msg.coa_radius_m)]
        features.append({
            "type": "Feature",
            "geometry": {"type": "Polygon", "coordinates": [[*ring, ring[0]]]},
            "properties": {"name": f"P{i}: circle of acceptance, r = {msg.coa_radius_m:g} m",
                           "style": {"color": "#f28c1a", "weight": 1, "fillOpacity": 0.1}},
        })
    return json.dumps({"type": "FeatureCollection", "features": features})


def log_message(t_ns: int, level: str, name: str, logger: str, message: str) -> Derived:
    """A ``foxglove.Log`` on ``LOG_TOPIC`` of one line of process ``name``'s log; ``level`` is
    Python's name (``INFO``, ...); the text is ``logger: message`` (the message alone without one)."""
    text = f"{logger}: {message}" if logger else message
    return Derived(LOG_TOPIC, fg.Log(timestamp=timestamp(t_ns), level=LOG_LEVELS.get(level.upper(),
                                     fg.LogLevel.Unknown), message=text, name=name))


LOG_LEVELS = {"DEBUG": fg.LogLevel.Debug, "INFO": fg.LogLevel.Info, "WARNING": fg.LogLevel.Warning,
              "WARN": fg.LogLevel.Warning, "ERROR": fg.LogLevel.Error,
              "CRITICAL": fg.LogLevel.Fatal, "FATAL": fg.LogLevel.Fatal}
"""Python's logging levels as Foxglove's."""


@dataclass
class _Vessel:
    origin: GeoOrigin | None = None
    static_sent: bool = False
    hull_sent: bool = False
    truth_hull_sent: bool = False
    mission: tuple[Any, ...] | None = None
    pending_mission: MissionAccepted | None = None
    """An accepted mission heard before any origin: drawn once the origin is known."""


class FoxgloveDeriver:
    """Decoded bus messages in, ``Derived`` Foxglove messages out (the table in the module text).

    ``default_origin``: the NED origin until a vessel's ``nav/origin`` arrives (the scenario's);
    positions before any origin is known give no map channels. ``timestamp_ns``: a source's
    ``stamp_ns`` to the derived message's ``timestamp`` [ns since the Unix epoch] (identity in
    real time).
    """

    SOURCES: tuple[keys.KeySpec, ...] = (keys.SIM_TRUTH, keys.NAV_STATE, keys.NAV_ORIGIN, keys.GNSS,
                                         keys.SOLVE, keys.MISSION_ACCEPTED)
    """The keys ``feed`` uses; a writer need decode only these for it."""

    def __init__(self, default_origin: GeoOrigin | None = None,
                 timestamp_ns: Callable[[int], int] = lambda stamp_ns: stamp_ns) -> None:
        self._default = default_origin
        self._t = timestamp_ns
        self._vessels: dict[str, _Vessel] = {}
        self._sources: dict[str, tuple[str, _Vessel, str]] = {}
        """Per key fed: its vessel, that vessel's state, and the key's suffix as a topic name."""

    def feed(self, key: str, msg: Message) -> list[Derived]:
        found = self._sources.get(key)
        if found is None:
            parts = key.split("/", 2)
            if len(parts) != 3 or parts[0] != keys.ROOT:
                return []
            vessel = parts[1]
            v = self._vessels.get(vessel)
            if v is None:
                v = self._vessels[vessel] = _Vessel()
            found = self._sources[key] = (vessel, v, parts[2].replace("/", "-"))
        vessel, v, source = found
        out: list[Derived] = []
        if isinstance(msg, NavOrigin):
            heard = GeoOrigin(msg.lat_rad, msg.lon_rad, msg.alt_m)
            if heard != v.origin:  # the same origin again keeps its precomputed terms
                v.origin = heard
        origin = v.origin or self._default
        t_ns = self._t(msg.stamp_ns)
        if isinstance(msg, GnssFix):
            var = msg.horizontal_std_m ** 2 if msg.horizontal_std_m is not None else None
            out.append(Derived(
                f"{FOXGLOVE_ROOT}/{vessel}/{source}",
                location_fix(t_ns, vessel, msg.lat_rad, msg.lon_rad, msg.alt_m,
                             enu_covariance_m2=None if var is None else
                             [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, 0.0],
                             covariance_type=fg.LocationFixPositionCovarianceType.Unknown if var is None
                             else fg.LocationFixPositionCovarianceType.DiagonalKnown), key))
        elif isinstance(msg, SimTruth | StateEstimate):
            truth = isinstance(msg, SimTruth)
            if origin is not None:
                lat, lon, alt = origin.to_geodetic(msg.x_m, msg.y_m, 0.0)
                cov = None if truth else enu_position_covariance(msg)  # type: ignore[arg-type]
                out.append(Derived(
                    f"{FOXGLOVE_ROOT}/{vessel}/{source}",
                    location_fix(t_ns, vessel, lat, lon, alt, heading_rad=msg.psi_rad,
                                 enu_covariance_m2=cov,
                                 covariance_type=fg.LocationFixPositionCovarianceType.Known
                                 if cov is not None else fg.LocationFixPositionCovarianceType.Unknown),
                    key))
            out += self._frames(vessel, v, key, t_ns, msg, truth)
        elif isinstance(msg, SolveRecord):
            out.append(self._prediction(vessel, key, t_ns, msg))
        elif isinstance(msg, MissionAccepted):
            v.pending_mission = msg
        if v.pending_mission is not None and origin is not None:
            out += self._mission(vessel, v, v.pending_mission, origin)
            v.pending_mission = None
        return out

    # -- 3D -----------------------------------------------------------------------------------

    def _frames(self, vessel: str, v: _Vessel, key: str, t_ns: int, msg: SimTruth | StateEstimate,
                truth: bool) -> list[Derived]:
        out = []
        ned = f"{vessel}/ned"
        if not v.static_sent:
            v.static_sent = True
            out.append(Derived(f"{FOXGLOVE_ROOT}/{vessel}/tf/ned", fg.FrameTransform(
                timestamp=timestamp(t_ns), parent_frame_id=MAP_FRAME, child_frame_id=ned,
                translation=fg.Vector3(x=0.0, y=0.0, z=0.0),
                rotation=fg.Quaternion(x=_NED_IN_ENU[0], y=_NED_IN_ENU[1], z=_NED_IN_ENU[2],
                                       w=_NED_IN_ENU[3])), key))
        child = f"{vessel}/{'truth' if truth else 'body'}"
        out.append(Derived(f"{FOXGLOVE_ROOT}/{vessel}/tf/{'truth' if truth else 'body'}",
                           fg.FrameTransform(timestamp=timestamp(t_ns), parent_frame_id=ned,
                                             child_frame_id=child,
                                             translation=fg.Vector3(x=msg.x_m, y=msg.y_m, z=0.0),
                                             rotation=_yaw(msg.psi_rad)), key))
        sent = v.truth_hull_sent if truth else v.hull_sent
        if not sent:
            if truth:
                v.truth_hull_sent = True
            else:
                v.hull_sent = True
            out.append(Derived(f"{FOXGLOVE_ROOT}/{vessel}/scene/{'truth' if truth else 'vessel'}",
                               self._hull(child, t_ns, truth), key))
        return out

    def _hull(self, frame: str, t_ns: int, truth: bool) -> fg.SceneUpdate:
        length, beam, height = HULL_M
        color = _color("truth" if truth else "hull")
        return fg.SceneUpdate(entities=[fg.SceneEntity(
            timestamp=timestamp(t_ns), frame_id=frame, id="truth" if truth else "vessel",
            frame_locked=True,
            cubes=[fg.CubePrimitive(pose=_identity_pose(),
                                    size=fg.Vector3(x=length, y=beam, z=height), color=color)],
            arrows=[fg.ArrowPrimitive(pose=_identity_pose(), shaft_length=0.8 * length,
                                      shaft_diameter=0.05, head_length=0.25, head_diameter=0.15,
                                      color=color)],
            metadata=[fg.KeyValuePair(key="what", value=f"simulated vessel ({keys.SIM_TRUTH.suffix})"
                                      if truth else f"estimated vessel ({keys.NAV_STATE.suffix})")])])

    def _prediction(self, vessel: str, key: str, t_ns: int, msg: SolveRecord) -> Derived:
        topic = f"{FOXGLOVE_ROOT}/{vessel}/scene/prediction"
        pts = list(zip(msg.predicted_x_m, msg.predicted_y_m, strict=False))
        if not pts:  # no plan this step (a fallback): nothing stale stays drawn
            return Derived(topic, fg.SceneUpdate(deletions=[fg.SceneEntityDeletion(
                timestamp=timestamp(t_ns), type=fg.SceneEntityDeletionType.MatchingId,
                id="prediction")]), key)
        return Derived(topic, fg.SceneUpdate(entities=[fg.SceneEntity(
            timestamp=timestamp(t_ns), frame_id=f"{vessel}/ned", id="prediction",
            lines=[fg.LinePrimitive(type=fg.LinePrimitiveLineType.LineStrip, pose=_identity_pose(),
                                    thickness=0.04, points=[fg.Point3(x=x, y=y, z=0.0) for x, y in pts],
                                    color=_color("prediction"))],
            metadata=[fg.KeyValuePair(key="controller", value=msg.controller),
                      fg.KeyValuePair(key="status", value=msg.status)])]), key)

    def _mission(self, vessel: str, v: _Vessel, msg: MissionAccepted, origin: GeoOrigin
                 ) -> list[Derived]:
        # The controller republishes its mission once a second in real time: draw it once per
        # acceptance (the Map panel draws every GeoJSON message of a file at once).
        ident = (msg.accepted_ns, msg.mission_id, tuple(msg.waypoints_m()), msg.coa_radius_m)
        if ident == v.mission:
            return []
        v.mission = ident
        key = keys.MISSION_ACCEPTED.key(vessel)
        t_ns = self._t(msg.stamp_ns)
        pts = msg.waypoints_m()
        lines = [fg.LinePrimitive(type=fg.LinePrimitiveLineType.LineStrip, pose=_identity_pose(),
                                  thickness=0.05, color=_color("path"),
                                  points=[fg.Point3(x=x, y=y, z=0.0) for x, y in pts])]
        lines += [fg.LinePrimitive(type=fg.LinePrimitiveLineType.LineLoop, pose=_identity_pose(),
                                   thickness=0.03, color=_color("circle"),
                                   points=[fg.Point3(x=a, y=b, z=0.0)
                                           for a, b in circle_ned(x, y, msg.coa_radius_m)])
                  for x, y in pts]
        texts = [fg.TextPrimitive(pose=fg.Pose(position=fg.Vector3(x=x, y=y, z=-0.5),
                                               orientation=fg.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
                                  billboard=True, font_size=14.0, scale_invariant=True,
                                  color=_color("text"), text=f"P{i}")
                 for i, (x, y) in enumerate(pts)]
        scene = fg.SceneUpdate(entities=[fg.SceneEntity(
            timestamp=timestamp(t_ns), frame_id=f"{vessel}/ned", id="mission", lines=lines,
            texts=texts, metadata=[fg.KeyValuePair(key="mission_id", value=msg.mission_id),
                                   fg.KeyValuePair(key="coa_radius_m", value=f"{msg.coa_radius_m:g}")])])
        return [Derived(f"{FOXGLOVE_ROOT}/{vessel}/mission",
                        fg.GeoJson(geojson=mission_geojson(msg, origin)), key),
                Derived(f"{FOXGLOVE_ROOT}/{vessel}/scene/mission", scene, key)]
