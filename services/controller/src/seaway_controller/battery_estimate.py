"""The battery's usable energy left, as the energy budget prices it: the lowest of the estimates.

An autopilot's remaining fraction is often its count of the charge drawn against the capacity it
was told (ArduPilot's ``BATT_CAPACITY``), blind to a pack that was not full or has aged: its voltage
can say "low" while the fraction still says 98 %. So, for a report from the autopilot, the budget
takes the lowest of (``BatteryEstimateSource``):

* ``autopilot``: the latest report's remaining energy (its fraction x the usable energy, or the
  usable energy less what it counted drawn), less the energy the controller counted since;
* ``count``: the first report's remaining energy less everything the controller counted since
  (anchored anew on a new pack: the autopilot's figure rising ``RECHARGE_FRAC`` of the capacity
  from one report to the next, or its count of the energy drawn going back);
* ``voltage``: the pack's voltage on the vessel file's battery model (``seaway.vessel.battery``:
  linear from ``empty_voltage_v`` to ``full_voltage_v``), less what was counted since. Only while
  the voltage is within ``VOLTAGE_SPAN_MARGIN`` of that span beyond either end: a voltage outside it
  says the vessel file does not describe this pack (logged once), not that it is empty.

A voltage under load reads low, so the voltage estimate errs on the safe side. Ties go to the
earlier source above (so the source said does not flicker). The source is published
(``EnergyBudget.battery_source``) and logged when it changes. A report from the lockstep simulator
(source 'sim') is its own truth: taken as it is.

Units: energy [J], voltage [V].
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

from seaway.contract.messages import BatteryEstimateSource, BatteryState
from seaway.vessel.battery import BatteryParams

log = logging.getLogger("seaway_controller.battery")

RECHARGE_FRAC = 0.1
"""The autopilot's figure rising this fraction of the capacity between reports is a new pack."""
VOLTAGE_SPAN_MARGIN = 0.1
"""A voltage further than this fraction of (full - empty) outside that span is not this pack's."""
TIE_FRAC = 1e-3
"""Estimates closer than this fraction of the capacity are a tie (the earlier source keeps it)."""


def voltage_energy_j(volts: float, pack: BatteryParams) -> float | None:
    """The usable energy left in ``pack`` at ``volts`` on its linear model [J]; None if the
    voltage is outside its span by more than ``VOLTAGE_SPAN_MARGIN``."""
    span = pack.full_v - pack.empty_v
    if not pack.empty_v - VOLTAGE_SPAN_MARGIN * span <= volts <= pack.full_v + VOLTAGE_SPAN_MARGIN * span:
        return None
    return min(1.0, max(0.0, (volts - pack.empty_v) / span)) * pack.energy_j


@dataclass
class BatteryTrack:
    """The battery's last report and the energy the controller counted since; see the module."""

    pack: BatteryParams | None = None
    report: BatteryState | None = None
    counted_at_report_j: float = 0.0
    source: BatteryEstimateSource | None = None  # the lowest at the last ``remaining_j``
    _anchor: tuple[float, float] | None = field(default=None, repr=False)  # (J, counted then)
    _taken: BatteryState | None = field(default=None, repr=False)  # the report anchored against
    _voltage_refused: bool = field(default=False, repr=False)

    def remaining_j(self, counted_now_j: float) -> float | None:
        """The usable energy left now [J] (None: no report with an energy yet), the lowest
        estimate; ``source`` says which."""
        r = self.report
        if r is None or r.remaining_j is None:
            return None
        since = max(0.0, counted_now_j - self.counted_at_report_j)
        estimates: dict[BatteryEstimateSource, float] = {"autopilot": r.remaining_j - since}
        if r.source == "autopilot":
            self._anchor_on(r)
            if self._anchor is not None:
                estimates["count"] = self._anchor[0] - max(0.0, counted_now_j - self._anchor[1])
            volts = self._voltage_estimate(r)
            if volts is not None:
                estimates["voltage"] = volts - since
        capacity = r.capacity_j or (self.pack.energy_j if self.pack is not None else 0.0)
        tie = TIE_FRAC * capacity
        source, best = "autopilot", estimates["autopilot"]
        for name in ("count", "voltage"):
            value = estimates.get(name)
            if value is not None and value < best - tie:
                source, best = name, value
        if source != self.source:
            said = ", ".join(f"{k} {v:.0f} J" for k, v in estimates.items())
            log.info("battery: the energy budget takes the %s estimate, the lowest (%s)", source, said)
            self.source = source  # type: ignore[assignment]
        return max(0.0, best)

    def _anchor_on(self, r: BatteryState) -> None:
        if r is self._taken:
            return
        before, self._taken = self._taken, r
        assert r.remaining_j is not None
        capacity = r.capacity_j or (self.pack.energy_j if self.pack is not None else 0.0)
        # A new pack: the autopilot's own figure rose, or its count of the energy drawn restarted.
        rose = (before is not None and before.remaining_j is not None
                and r.remaining_j > before.remaining_j + RECHARGE_FRAC * capacity)
        restarted = (before is not None and before.consumed_j is not None
                     and r.consumed_j is not None and r.consumed_j < before.consumed_j)
        if self._anchor is None or rose or restarted:
            self._anchor = (r.remaining_j, self.counted_at_report_j)

    def _voltage_estimate(self, r: BatteryState) -> float | None:
        if self.pack is None or r.voltage_v is None:
            return None
        value = voltage_energy_j(r.voltage_v, self.pack)
        if value is None and not self._voltage_refused:
            self._voltage_refused = True
            log.warning("battery: %.2f V is outside the vessel file's pack (%.2f-%.2f V): its "
                        "voltage is not used to estimate the energy left", r.voltage_v,
                        self.pack.empty_v, self.pack.full_v)
        return value
