"""Keep the autopilot's own fence equal to the operating area: upload, set the parameters, read it
all back. Pure: messages, the area and time in; MAVLink to send out; the core owns one.

The area comes from ``keys.AREA_ACTIVE`` (``ActiveArea``, local NED) and becomes WGS84 through the run's
origin (``keys.NAV_ORIGIN``, or the run description's). A sync runs when the area changes (its
geometry: the controller's 1 Hz re-publication of the same area is no change), when the link comes
up, and when the autopilot rebooted without the link dropping (``epoch``), in steps:

1. upload the fence items (``MAV_MISSION_TYPE_FENCE``), then the rally points (``..._RALLY``);
2. set the fence's parameters (``fence_plan.FENCES``), each PARAM_SET answered by its PARAM_VALUE;
3. download the fence and the rally points, read each parameter again, and compare with what was
   meant: ``verified``, or ``mismatch`` saying where (logged at WARNING).

A transfer that fails (no answer after the retries, a refusal) is logged at WARNING and the whole
sync retried after ``RETRY_S``; an area the autopilot cannot hold (too many items: refused here for
PX4's known limit, or by the autopilot's ``NO_SPACE``) is ``refused``, naming the fields, and not
retried until the area changes. Everything that happens shows in ``report()``
(``VehicleStatus.autopilot_fence``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from seaway.area.model import AreaError, OperatingArea
from seaway.contract.messages import ActiveArea, AutopilotFence, AutopilotFenceState
from seaway.vessel.frames import GeoOrigin

from seaway_vehicle_io import fence_plan as plan
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.mission_transfer import (
    TRANSFER_MESSAGES,
    MissionItem,
    Transfer,
    TransferOutput,
)

log = logging.getLogger("seaway.vehicle_io")

RETRY_S = 10.0  # a failed sync (no answer) is tried again after this long
FENCE = mavlink.MAV_MISSION_TYPE_FENCE
RALLY = mavlink.MAV_MISSION_TYPE_RALLY


@dataclass(frozen=True)
class SendParamSet:
    target_system: int
    target_component: int
    param_id: str
    value: float  # as on the wire (``FenceParam.wire_value``)
    param_type: int


@dataclass(frozen=True)
class SendParamRead:
    """PARAM_REQUEST_READ by name (the fence's own read-back; the core's start-up read is apart)."""

    target_system: int
    target_component: int
    param_id: str


FenceOutput = TransferOutput | SendParamSet | SendParamRead


@dataclass
class _ParamStep:
    """Set (``write``) or read back one parameter, until its PARAM_VALUE arrives."""

    param: plan.FenceParam
    write: bool
    sent_ns: int = 0
    sends: int = 0
    value: float | None = None


class FenceSync:
    """The autopilot's fence, kept equal to the operating area (see the module docstring)."""

    def __init__(self, timeout_s: float, attempts: int) -> None:
        self.timeout_ns = round(timeout_s * 1e9)
        self.attempts = attempts
        self.origin: GeoOrigin | None = None
        self.area: OperatingArea | None = None
        self.area_since_ns = 0
        self._target: tuple[int, int] | None = None
        self._autopilot: str | None = None
        self._epoch: object = None
        self._dirty = False
        self._steps: list[Transfer | _ParamStep] = []
        self._meant: dict[int, tuple[MissionItem, ...]] = {}
        self._read: dict[str, float] = {}
        self._mismatch: list[str] = []
        self._retry_ns: int | None = None
        self._state: AutopilotFenceState | None = None
        self._detail = ""
        self._fence: plan.AutopilotFence | None = None
        self._discarded: str | None = None  # the autopilot said it does not enforce part of it

    # -- inputs --------------------------------------------------------------------------------------

    def set_origin(self, origin: GeoOrigin) -> None:
        if origin != self.origin:
            self.origin = origin
            self._dirty = True

    def set_area(self, msg: ActiveArea) -> None:
        """The area in force (``keys.AREA_ACTIVE``): a sync when its geometry changed."""
        try:
            area = msg.to_area()
        except AreaError as err:  # a message always holds a valid area; never trust it blindly
            log.warning("the active area not used for the autopilot's fence: %s", err)
            return
        if self.area is None or _geometry(area) != _geometry(self.area):
            self._dirty = True
        self.area, self.area_since_ns = area, msg.since_ns

    def on_mavlink(self, msg: Any, now_ns: int) -> list[FenceOutput]:
        """A mission-protocol message (``TRANSFER_MESSAGES``) from the locked autopilot."""
        step = self._steps[0] if self._steps else None
        if isinstance(step, Transfer) and msg.get_type() in TRANSFER_MESSAGES:
            out: list[FenceOutput] = list(step.on_mavlink(msg, now_ns))
            return out + self._advance(now_ns)
        return []

    def on_param_value(self, name: str, value: float, now_ns: int) -> list[FenceOutput]:
        """A decoded PARAM_VALUE (any: the core hears them all)."""
        step = self._steps[0] if self._steps else None
        if not isinstance(step, _ParamStep) or name != step.param.name:
            return []
        step.value = value
        return self._advance(now_ns)

    def on_text(self, text: str) -> None:
        """A STATUSTEXT or decoded EVENT: PX4 discards a zone that does not contain home (or, when
        armed, the vehicle) after accepting the upload, and says only this ("Geofence invalid,
        doesn't contain Home position"). The items read back as uploaded, but the autopilot does
        not hold them: a mismatch, not 'verified'."""
        if plan.DISCARD_TEXT not in text.lower() or self.area is None or self._state is None:
            return
        self._discarded = text
        if self._state == "verified":
            self._verdict()

    def tick(self, now_ns: int, target: tuple[int, int] | None, autopilot: str | None,
             epoch: object) -> list[FenceOutput]:
        """Drive the sync: ``target`` (system, component) of the locked autopilot (None: no link),
        its profile's name, and ``epoch``, whose change (a new link, a reboot) means the
        autopilot's fence is to be checked again."""
        if target is None or autopilot not in plan.FENCES:
            if self._steps:
                self._steps = []
                self._state, self._detail = ("failed", "the link to the autopilot was lost") \
                    if self._state == "uploading" else (self._state, self._detail)
            self._target = None
            return []
        if (target, autopilot, epoch) != (self._target, self._autopilot, self._epoch):
            self._target, self._autopilot, self._epoch = target, autopilot, epoch
            self._dirty = True
        if self._retry_ns is not None and now_ns >= self._retry_ns:
            self._retry_ns = None
            self._dirty = True
        if self._dirty and self.area is not None and self.origin is not None:
            return self._begin(now_ns)
        step = self._steps[0] if self._steps else None
        if isinstance(step, Transfer):
            out: list[FenceOutput] = list(step.tick(now_ns))
            return out + self._advance(now_ns)
        if isinstance(step, _ParamStep) and now_ns >= step.sent_ns + self.timeout_ns:
            if step.sends >= self.attempts:
                return self._fail(f"no PARAM_VALUE for {step.param.name} after {step.sends} "
                                  f"attempts of {self.timeout_ns / 1e9:g} s", now_ns)
            return self._send_param(step, now_ns)
        return []

    def next_due_ns(self) -> int | None:
        step = self._steps[0] if self._steps else None
        if isinstance(step, Transfer):
            return step.next_due_ns()
        if isinstance(step, _ParamStep):
            return step.sent_ns + self.timeout_ns
        return self._retry_ns

    def report(self) -> AutopilotFence | None:
        if self._state is None or self.area is None:
            return None
        fence = self._meant.get(FENCE, ())
        rally = self._meant.get(RALLY, ())
        action = ", ".join(f"{p.name}={p.value} ({p.meaning})" for p in self._params())
        return AutopilotFence(state=self._state, detail=self._detail[:2000],
                              area_since_ns=self.area_since_ns, fence_items=len(fence),
                              rally_points=len(rally), action=action)

    # -- the steps ----------------------------------------------------------------------------------

    def _params(self) -> tuple[plan.FenceParam, ...]:
        if self._fence is None or self.area is None:
            return ()
        return self._fence.disable if self.area.empty else self._fence.enable

    def _begin(self, now_ns: int) -> list[FenceOutput]:
        assert self.area is not None and self.origin is not None and self._target is not None
        assert self._autopilot is not None
        self._dirty, self._retry_ns, self._mismatch, self._read = False, None, [], {}
        self._discarded = None
        self._fence = plan.FENCES[self._autopilot]
        self._meant = {FENCE: plan.fence_items(self.area, self.origin),
                       RALLY: plan.rally_items(self.area, self.origin)}
        why = plan.refusal(self.area, self._fence, self._autopilot)
        if why is not None:
            self._steps = []
            return self._refuse(why)
        t, n, a = self._target, self.timeout_ns, self.attempts
        self._steps = [Transfer(t, FENCE, n, a, upload=self._meant[FENCE]),
                       Transfer(t, RALLY, n, a, upload=self._meant[RALLY]),
                       *(_ParamStep(p, write=True) for p in self._params()),
                       Transfer(t, FENCE, n, a), Transfer(t, RALLY, n, a),
                       *(_ParamStep(p, write=False) for p in self._params())]
        self._state = "uploading"
        self._detail = (f"{len(self._meant[FENCE])} fence items, {len(self._meant[RALLY])} rally "
                        "points")
        log.info("uploading the operating area to the autopilot as its fence: %s", self._detail)
        return self._start_step(now_ns)

    def _start_step(self, now_ns: int) -> list[FenceOutput]:
        step = self._steps[0]
        if isinstance(step, Transfer):
            return list(step.start(now_ns))
        return self._send_param(step, now_ns)

    def _send_param(self, step: _ParamStep, now_ns: int) -> list[FenceOutput]:
        assert self._target is not None
        step.sends += 1
        step.sent_ns = now_ns
        ts, tc = self._target
        p = step.param
        if step.write:
            return [SendParamSet(ts, tc, p.name, p.wire_value(), p.param_type)]
        return [SendParamRead(ts, tc, p.name)]

    def _advance(self, now_ns: int) -> list[FenceOutput]:
        """Finish the current step if it is done, start the next; the verdict after the last."""
        step = self._steps[0] if self._steps else None
        if isinstance(step, Transfer):
            if step.result is None:
                return []
            if step.result != "ok":
                if step.upload is not None and "NO_SPACE" in step.result and self.area is not None:
                    self._steps = []
                    what = (plan.fence_item_count(self.area) if step.mission_type == FENCE
                            else "rally_points")
                    return self._refuse(f"{step.result}: the operating area is "
                                        f"{len(step.upload)} items ({what}), more than the "
                                        "autopilot stores")
                return self._fail(step.result, now_ns)
            if step.upload is None:
                self._mismatch += plan.differences(step.kind.split()[0],
                                                   self._meant[step.mission_type], step.items)
        elif isinstance(step, _ParamStep):
            assert step.value is not None
            if not step.write and step.value != step.param.value:
                self._mismatch.append(f"{step.param.name} = {step.value:g}, set to "
                                      f"{step.param.value} ({step.param.meaning})")
        else:
            return []
        self._steps.pop(0)
        if self._steps:
            return self._start_step(now_ns)
        return self._verdict()

    def _verdict(self) -> list[FenceOutput]:
        if self._discarded is not None:
            self._mismatch.append(f"the autopilot does not enforce all of it: "
                                  f"{self._discarded!r}")
            self._discarded = None
        if self._mismatch:
            self._state, self._detail = "mismatch", "; ".join(self._mismatch)
            log.warning("the autopilot's fence DIFFERS from the operating area: %s", self._detail)
        else:
            self._state = "verified"
            self._detail = (f"{len(self._meant[FENCE])} fence items, {len(self._meant[RALLY])} "
                            "rally points and the parameters read back as uploaded")
            log.info("the autopilot holds the operating area as its fence: %s; %s", self._detail,
                     ", ".join(f"{p.name}={p.value} ({p.meaning})" for p in self._params()))
        return []

    def _fail(self, why: str, now_ns: int) -> list[FenceOutput]:
        self._steps = []
        self._state, self._detail = "failed", why
        self._retry_ns = now_ns + round(RETRY_S * 1e9)
        log.warning("the autopilot's fence was not set: %s; trying again in %.0f s", why, RETRY_S)
        return []

    def _refuse(self, why: str) -> list[FenceOutput]:
        self._state, self._detail = "refused", why
        log.warning("the operating area cannot be the autopilot's fence: %s", why)
        return []


def _geometry(area: OperatingArea) -> tuple[object, ...]:
    """What of an area goes to the autopilot (names do not)."""
    return (None if area.keep_in is None else area.keep_in.vertices_m,
            tuple(p.vertices_m for p in area.keep_out_polygons),
            tuple((c.center_m, c.radius_m) for c in area.keep_out_circles),
            tuple(r.position_m for r in area.rally_points))
