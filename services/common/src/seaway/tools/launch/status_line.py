"""The launcher's live status line: per vessel, what its mission, motion and energy budget are now.

On a terminal it is one line rewritten in place (``\\r``, then clear to the end of the line), fitted
to the terminal's width as it is at each rewrite: a line longer than the terminal wraps, and the
carriage return then goes back only to the start of its last row, so every rewrite would leave rows
behind. To fit, the least important fields are abbreviated first, then left out (``fit``). When the
output is not a terminal (a pipe, a log file) each vessel's whole line is printed every
``PRINT_EVERY_S`` seconds instead.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import shutil
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TextIO

from seaway.contract import keys
from seaway.contract.messages import (
    EnergyBudget,
    MissionStatus,
    StateEstimate,
    ThrustCommand,
)
from seaway.runtime.bus import Bus
from seaway.runtime.bus_typed import Every, Newest
from seaway.runtime.ratelog import RateLimitedLog

log = logging.getLogger(__name__)
_ratelog = RateLimitedLog(log, every_s=60.0)

DECISION_LABELS = {"warn": "LOW ENERGY", "return": "RETURNING", "hold": "HOLDING"}
"""How the status line names an energy budget's decision (``EnergyBudget.decision``, not 'none')."""

PRINT_EVERY_S = 5.0
"""When the output is not a terminal: the period of the printed lines [s]."""

SEPARATOR = " | "
"""Between the fields of one vessel."""

VESSEL_SEPARATOR = " || "
"""Between the vessels of a fleet on one line."""

UNKNOWN = "?"
"""What a field shows for a value it cannot show (not finite, absurdly large, or failing)."""
MAX_SHOWN = 1e9
"""Numbers at or beyond this magnitude are shown as ``UNKNOWN``: a status line has no room for a
valid but absurd value's 200 digits, and no operator reads them."""


def number(x: float | None, spec: str) -> str:
    """``x`` formatted with ``spec``, or ``UNKNOWN`` if it is None, not finite or absurdly large."""
    if x is None or not math.isfinite(x) or abs(x) >= MAX_SHOWN:
        return UNKNOWN
    return format(x, spec)


def energy_text(j: float | None) -> str:
    """An energy for the status line, three significant figures in J, kJ or MJ ('-' for none)."""
    if j is None or not math.isfinite(j):
        return "-"
    if abs(j) >= MAX_SHOWN * 1e6:
        return f"{UNKNOWN} MJ"
    unit, v = next((u, j / k) for u, k in (("MJ", 1e6), ("kJ", 1e3), ("J", 1.0)) if abs(j) >= k or u == "J")
    digits = 0 if abs(v) >= 99.95 else 1 if abs(v) >= 9.995 else 2
    return f"{v:.{digits}f} {unit}"


@dataclass(frozen=True)
class Field:
    """One field of the line: its whole text, a shorter one, and how important it is (``rank``: 0
    is kept longest; a fit abbreviates, then leaves out, the highest ranks first)."""

    rank: int
    full: str
    short: str | None = None


# The ranks: what an operator must see at any width first (whose line, what the mission does, an
# energy decision, when), then motion, then the budget's figures.
RANK_VESSEL, RANK_MISSION, RANK_DECISION, RANK_TIME = 0, 1, 2, 3
RANK_SPEED, RANK_XTE, RANK_BATTERY, RANK_USED, RANK_TO_FINISH, RANK_TO_HOME = 4, 5, 6, 7, 8, 9
RANK_ONLY_VESSEL = 10
"""The vessel's name when the launch runs only that one: the first to go."""


def fit(fields: list[Field], width: int | None, separator: str = SEPARATOR) -> str:
    """The fields joined by ``separator`` in at most ``width`` characters (None: no limit).

    While too long: the fields' short forms, least important first; then without the least
    important fields (the most important one stays); then cut, ending in ``...``."""
    texts = [f.full for f in fields]
    shown = list(range(len(fields)))

    def line() -> str:
        return separator.join(texts[i] for i in shown)

    if width is None or len(line()) <= width:
        return line()
    by_rank = sorted(range(len(fields)), key=lambda i: fields[i].rank, reverse=True)
    for i in by_rank:
        if fields[i].short is not None:
            texts[i] = fields[i].short
            if len(line()) <= width:
                return line()
    for i in by_rank[:-1]:
        shown.remove(i)
        if len(line()) <= width:
            return line()
    text = line()
    return text if len(text) <= width else text[: max(width - 3, 0)] + "..."[:width]


class StatusLine:
    """The live line: per vessel, leg, the estimator's motion fault if any
    (``StateEstimate.motion_fault``), speed, cross-track error and the energy budget: energy used,
    to finish the mission, to get home, the battery's remaining energy against its reserve and,
    once taken, the decision (``mission/energy``; the mission status's figures before any budget).

    ``t`` is the run's time: the wall time since the start in real time; in lockstep the simulated
    time (the latest state's stamp) and, beside it, how many times faster than real time it goes
    (simulated over wall seconds since the first state)."""

    def __init__(
        self, vessels: list[str], lockstep: bool = False, commands: bool = False, out: TextIO | None = None
    ) -> None:
        self.lockstep = lockstep
        self.commands = commands
        """Show the latest thrust command while there is no mission status (a run that sends no
        mission: ``seaway identify fly`` flying its manoeuvre, say)."""
        self.vessels = list(vessels)
        self.mission: dict[str, MissionStatus | None] = dict.fromkeys(self.vessels)
        self.state: dict[str, StateEstimate | None] = dict.fromkeys(self.vessels)
        self.energy: dict[str, EnergyBudget | None] = dict.fromkeys(self.vessels)
        self.thrust: dict[str, ThrustCommand | None] = dict.fromkeys(self.vessels)
        self.decided: dict[str, EnergyBudget | None] = dict.fromkeys(self.vessels)
        """The budget of the period each vessel's decision was taken (its figures say why)."""
        self.out = out or sys.stdout
        self.tty = self.out.isatty()
        self._last_print = 0.0
        self._first: tuple[float, float] | None = None  # lockstep: (sim s, wall s) of the first state
        self._moved: tuple[float, float] | None = None  # lockstep: (sim s, wall s) when it last moved
        self._newest: dict[
            str, tuple[Newest[MissionStatus], Newest[StateEstimate], Newest[ThrustCommand] | None]
        ] = {}
        self._budgets: dict[str, Every[EnergyBudget]] = {}
        self.without: dict[str, list[str]] = {}
        """Per vessel, the services the run goes on without (failed for good, not required): set
        by the launcher (``Supervisor.failed_optional``)."""

    def watch(self, bus: Bus) -> None:
        """Keep the latest mission status, state and energy budget of every vessel.

        In lockstep they come hundreds a second and the line shows a few a second: status, state and
        commands are decoded only when shown (``Bus.newest``, ``pull``). Every budget is decoded
        then too (``Bus.every``), as the one of the period a decision was taken must be kept."""
        for v in self.vessels:
            self._newest[v] = (
                bus.newest(keys.MISSION_STATUS, vessel=v),
                bus.newest(keys.NAV_STATE, vessel=v),
                bus.newest(keys.THRUST, vessel=v) if self.commands else None,
            )
            self._budgets[v] = bus.every(keys.MISSION_ENERGY, vessel=v)

    def pull(self) -> None:
        """Take the newest status, state and command heard, and every budget (decoding them now)."""
        for v, budgets in self._budgets.items():
            for budget in budgets.take():
                self.on_energy(v, budget)
        for v, (mission, state, thrust) in self._newest.items():
            self.mission[v], self.state[v] = mission.get(), state.get()
            if thrust is not None:
                self.thrust[v] = thrust.get()

    def on_energy(self, vessel: str, budget: EnergyBudget) -> None:
        """The vessel's latest budget; the first one of a decision is kept for its figures."""
        self.energy[vessel] = budget
        before = self.decided[vessel]
        if budget.decision != "none" and (before is None or before.decided_ns != budget.decided_ns):
            self.decided[vessel] = budget

    def text(self, t_s: float, width: int | None = None) -> str:
        """One line for every vessel (a fleet's vessels joined by ``||``), in at most ``width``
        characters (None: whole); each vessel gets an equal share."""
        share = None
        if width is not None:
            gaps = len(VESSEL_SEPARATOR) * (len(self.vessels) - 1)
            share = max((width - gaps) // len(self.vessels), 1)
        return VESSEL_SEPARATOR.join(self.vessel_text(v, t_s, share) for v in self.vessels)

    def vessel_text(self, vessel: str, t_s: float, width: int | None = None) -> str:
        """``t_s``: wall seconds since the run started; ``width``: at most this many characters."""
        return fit(self.fields(vessel, t_s), width)

    def fields(self, vessel: str, t_s: float) -> list[Field]:
        """The vessel's fields, in the order shown.

        Never raises: the messages are another process's, valid yet possibly absurd, and the
        launcher redraws the line several times a second with no handler around it. A field that
        cannot be made shows ``UNKNOWN`` instead (logged, at most once a minute per field)."""
        s = self.state[vessel]
        out = [
            Field(RANK_VESSEL if len(self.vessels) > 1 else RANK_ONLY_VESSEL, vessel),
            _guarded(vessel, "time", RANK_TIME, lambda: [self.time_field(s, t_s)]),
            *_guarded_all(vessel, "mission", RANK_MISSION, lambda: self.mission_fields(vessel)),
        ]
        for service in self.without.get(vessel, ()):  # the run goes on without it: say so first
            out.append(Field(RANK_DECISION, "NOT RECORDING", "NOT REC") if service == "recorder"
                       else Field(RANK_DECISION, f"NO {service.upper()}", f"NO {service.upper()}"))
        if s is not None and s.motion_fault is not None:  # the vessel does not do what it is told
            out.append(Field(RANK_DECISION, f"MOTION FAULT {s.motion_fault}", f"FAULT {s.motion_fault}"))
        elif s is not None and s.thrust_short_side is not None:  # a thruster gives less (estimator)
            short = number(None if s.thrust_short_frac is None else 100 * s.thrust_short_frac, ".0f")
            side = s.thrust_short_side.upper()
            out.append(Field(RANK_DECISION, f"{side} THRUSTER {short} % SHORT", f"{side} -{short}%"))
        if s is not None:
            speed = number(math.hypot(s.u_mps, s.v_mps), ".2f")
            out.append(Field(RANK_SPEED, f"speed {speed:>4} m/s", f"{speed} m/s"))
        return out + _guarded_all(vessel, "energy", RANK_USED, lambda: self.energy_fields(vessel))

    def mission_fields(self, vessel: str) -> list[Field]:
        """The mission's state and cross-track error, else the thrust commanded (``commands``)."""
        m = self.mission[vessel]
        if m is not None:
            leg = f"{m.active_leg}/{max(m.waypoint_count - 1, 0)}"
            out = [Field(RANK_MISSION, f"{m.state} leg {leg}", f"{m.state} {leg}")]
            if m.cross_track_m is not None:
                out.append(Field(RANK_XTE, f"xte {number(m.cross_track_m, '5.2f')} m",
                                 f"xte {number(m.cross_track_m, '.1f')}"))
            return out
        if self.commands and (c := self.thrust[vessel]) is not None:
            port, stbd = c.thrust_port_n, c.thrust_starboard_n
            return [Field(RANK_MISSION,
                          f"thrust {number(port, '+.2f')} / {number(stbd, '+.2f')} N ({c.source})",
                          f"{number(port, '+.1f')}/{number(stbd, '+.1f')} N")]
        return [Field(RANK_MISSION, "no mission status yet", "no status")]

    def energy_fields(self, vessel: str) -> list[Field]:
        """Energy used, to finish, to home, battery vs reserve, and the decision once taken: from
        the budget of the mission the status names, else the status's own figures."""
        m, b = self.mission[vessel], self.energy[vessel]
        if b is None or (m is not None and m.mission_id != b.mission_id):
            if m is None:
                return []
            return ([_used(m.energy_used_j)] if m.energy_used_j is not None else []) + (
                [_to_finish(m.energy_to_go_j)] if m.energy_to_go_j is not None else []
            )
        # Energy used: the status's count, every period (the budget's is priced once a second, so
        # it lags by up to a second's energy; the report's one figure is the status's).
        used = m.energy_used_j if m is not None and m.energy_used_j is not None else b.energy_used_j
        out = [
            _used(used),
            _to_finish(b.energy_to_go_j),
            Field(
                RANK_TO_HOME,
                f"to home {energy_text(b.energy_to_home_j)}",
                f"home {energy_text(b.energy_to_home_j)}",
            ),
        ]
        if b.battery_remaining_j is not None:
            battery = f"battery {energy_text(b.battery_remaining_j)}"
            out.append(
                Field(
                    RANK_BATTERY,
                    battery + (f" (reserve {energy_text(b.reserve_j)})" if b.reserve_j is not None else ""),
                    f"batt {energy_text(b.battery_remaining_j)}",
                )
            )
        if b.decision != "none":
            full = self.decision_text(vessel, b, m)
            out.append(Field(RANK_DECISION, full, full.split(":", 1)[0]))
        return out

    def decision_text(self, vessel: str, b: EnergyBudget, m: MissionStatus | None) -> str:
        label = DECISION_LABELS[b.decision]
        if b.decision == "return" and b.returning and m is not None and m.state == "complete":
            label = "RETURNED"
        d = self.decided[vessel]
        if d is None or d.decided_ns != b.decided_ns or None in (d.energy_to_home_j, d.battery_remaining_j):
            return f"{label}: {b.reason}" if b.reason else label  # its period was not heard
        return (
            f"{label}: energy to home {energy_text(d.energy_to_home_j)} + reserve "
            f"{energy_text(d.reserve_j or 0.0)} reached {energy_text(d.battery_remaining_j)} left"
        )

    def time_field(self, state: StateEstimate | None, wall_s: float) -> Field:
        if not self.lockstep:
            return Field(RANK_TIME, f"t {wall_s:5.0f} s", f"t {wall_s:.0f} s")
        if state is None:
            return Field(RANK_TIME, "sim t     - s", "t - s")
        sim_s = state.stamp_ns / 1e9  # a stamp is an int64 (MAX_STAMP_NS): a float holds it
        if self._first is None or sim_s < self._first[0]:  # the first state, or a new episode
            self._first = self._moved = (sim_s, wall_s)
        elif self._moved is None or sim_s != self._moved[0]:
            self._moved = (sim_s, wall_s)
        # The rate up to when simulated time last moved: a sim holding (the mission complete, no
        # command) is not a run going slower.
        assert self._moved is not None
        d_sim, d_wall = self._moved[0] - self._first[0], self._moved[1] - self._first[1]
        if d_wall <= 0.5:
            return Field(RANK_TIME, f"sim t {number(sim_s, '5.0f')} s", f"t {number(sim_s, '.0f')} s")
        rate = d_sim / d_wall
        return Field(
            RANK_TIME,
            f"sim t {number(sim_s, '5.0f')} s ({number(rate, '4.0f')}x real time)",
            f"t {number(sim_s, '.0f')} s {number(rate, '.0f')}x",
        )

    def width(self) -> int:
        """The characters a rewritten line may take: the width of the terminal written to, now (it
        may have been resized; ``$COLUMNS`` overrides, as for ``shutil.get_terminal_size``) less
        one, as a terminal may wrap on writing its last column.

        Asked of this line's own output, not of fd 1: in the launcher fd 1 is the refusal counter's
        pipe (``seaway.runtime.refusals``), which has no width."""
        columns = shutil.get_terminal_size().columns
        if not os.environ.get("COLUMNS", "").isdigit():
            # Not a terminal after all (or closed): shutil's answer stands, 80 at worst.
            with contextlib.suppress(OSError, ValueError, AttributeError):
                columns = os.get_terminal_size(self.out.fileno()).columns
        return max(columns - 1, 1)

    def show(self, t_s: float, final: bool = False) -> None:
        """On a terminal, rewrite the line in place (and end it when ``final``); else print each
        vessel's whole line every ``PRINT_EVERY_S`` seconds, and at the end."""
        now = time.monotonic()
        self.pull()
        if self.tty:
            self.out.write("\r" + self.text(t_s, self.width()) + "\x1b[K" + ("\n" if final else ""))
            self.out.flush()
        elif final or now - self._last_print >= PRINT_EVERY_S:
            for v in self.vessels:
                print(self.vessel_text(v, t_s), file=self.out, flush=True)
            self._last_print = now


def _guarded_all(vessel: str, what: str, rank: int, make: Callable[[], list[Field]]
                 ) -> list[Field]:
    """``make()``, or one ``UNKNOWN`` field of ``rank`` if it raises (named in the log)."""
    try:
        return make()
    except Exception:
        _ratelog.exception((vessel, what), "status line: vessel %s: cannot show its %s; shown as %r",
                           vessel, what, UNKNOWN)
        return [Field(rank, f"{what} {UNKNOWN}")]


def _guarded(vessel: str, what: str, rank: int, make: Callable[[], list[Field]]) -> Field:
    return _guarded_all(vessel, what, rank, make)[0]


def _used(j: float | None) -> Field:
    return Field(RANK_USED, f"used {energy_text(j)}")


def _to_finish(j: float | None) -> Field:
    return Field(RANK_TO_FINISH, f"to finish {energy_text(j)}", f"fin {energy_text(j)}")
