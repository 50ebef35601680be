"""Is the vessel doing what it is told? A pure detector of persistent disagreement between what the
model predicts from the commanded thrust and what the GNSS measures.

The filter explains a small, slow disagreement as a disturbance (wind, current) and a single bad
fix as an outlier; neither is a fault. What the filter cannot explain away is a vessel that does
not respond to its thrust: grounded, a fouled or stuck thruster, a hull held by static friction. A
filter that dead-reckons on the commanded thrust then reports a boat cruising on its track while
it lies still, and snaps back to the fixes each time enough of them are rejected.

Evidence, over a sliding window of ``window_s`` of GNSS fixes (each fix one sample):

* **commanded against measured speed**: the commanded speed is the steady surge speed the commanded
  thrust holds against the model's damping, ``(T1 + T2) / X_u`` [m/s] (zero while the autopilot
  withholds the thrust); the measured one the fixes' velocity over ground along the heading (their
  Doppler velocity: its mean is unbiased by the noise, where a mean speed would not be; the speed
  of the slope of their positions when a fix has none). A window whose mean commanded speed is at
  least ``min_commanded_speed_mps`` while the measured mean is below ``moving_ratio`` of it is
  ``not_moving``. A slow vessel (an economic cruise of a few cm/s) is judged the same way over
  ``slow_window_s``, from ``min_slow_speed_mps``: more fixes average the velocity's noise down to
  what such a speed needs;
* **prediction against measurement**: the share of fixes whose position (or velocity over ground)
  was gated out, and the mean normalised innovation squared of the positions, each at most the
  gate (chi-square, 2 dof: 2 on average when the filter is right; one outlier is not a fault). A
  rejection rate of at least ``max_reject_rate`` or a mean above ``max_mean_nis`` is
  ``not_as_modelled`` (the vessel moves, but not as the thrust says: a thruster stuck or lost),
  if the vessel makes less than ``lost_thrust_ratio`` of the commanded speed (when one is
  commanded): a vessel faster than its model (a robustness study's perturbed plant, a following
  current) does what it is told and more.

A fault is raised after ``onset_s`` of continuous suspicion and cleared with hysteresis: after
``clear_s`` of windows in which the vessel moved as commanded, or ``idle_clear_s`` of windows with
no suspicion at all (nothing commanded: no evidence either way; the mission was paused, and may be
tried again). A window spanning less than ``min_span_frac`` of ``window_s`` or holding fewer than
``min_samples`` fixes gives no verdict (a dropout): the state holds.

Pure: samples and times in, events out; no clock, no logging.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from pydantic import Field
from seaway.contract.config import ConfigModel
from seaway.contract.messages import MotionFaultKind
from seaway.contract.units import NS_PER_S


class MismatchConfig(ConfigModel):
    """The detector's thresholds (``EstimatorConfig.mismatch``); unknown fields are errors."""

    enabled: bool = Field(default=True, description="detect motion faults at all")
    window_s: float = Field(default=5.0, gt=0, le=120, description="sliding window of fixes [s]")
    slow_window_s: float = Field(default=30.0, gt=0, le=600, description="the window a slow "
                                 "vessel's speed is judged over [s]")
    min_slow_speed_mps: float = Field(default=0.02, gt=0, description="over slow_window_s, a "
                                      "window commanding less gives no speed evidence [m/s]")
    min_span_frac: float = Field(default=0.8, gt=0, le=1, description="a window must span this "
                                 "share of window_s to give a verdict")
    min_samples: int = Field(default=5, ge=2, description="fixes a window needs for a verdict")
    onset_s: float = Field(default=3.0, ge=0, le=600, description="continuous suspicion before the "
                           "fault is raised [s]")
    clear_s: float = Field(default=5.0, ge=0, le=600, description="continuous agreement under "
                           "commanded motion before it clears [s]")
    idle_clear_s: float = Field(default=15.0, ge=0, le=3600, description="continuous lack of "
                                "suspicion with nothing commanded before it clears [s]")
    min_commanded_speed_mps: float = Field(default=0.1, gt=0, description="a window commanding "
                                           "less gives no speed evidence [m/s]")
    moving_ratio: float = Field(default=0.3, gt=0, lt=1, description="measured below this share of "
                                "the commanded speed is not moving")
    lost_thrust_ratio: float = Field(default=0.8, gt=0, le=10, description="not_as_modelled needs "
                                     "the measured speed below this share of the commanded one")
    max_reject_rate: float = Field(default=0.3, gt=0, le=1, description="share of fixes gated out")
    max_mean_nis: float = Field(default=8.0, gt=0, description="mean position NIS (2 dof; 2 when "
                                "the filter is right)")


@dataclass(frozen=True)
class FixSample:
    """What one GNSS fix said about the filter. Times [ns], NED position [m], speeds [m/s]."""

    t_ns: int
    north_m: float
    east_m: float
    rejected: bool
    """Its position or its velocity over ground was gated out."""
    nis: float
    """The position's normalised innovation squared (before the update), at most the gate."""
    surge_over_ground_mps: float | None
    """The fix's velocity over ground along the filter's heading, when it has a velocity."""
    commanded_mps: float
    """The steady surge speed of the thrust the filter applied at the fix."""


@dataclass(frozen=True)
class Verdict:
    """One window's evidence."""

    commanded_mps: float
    measured_mps: float
    reject_rate: float
    mean_nis: float
    suspect: MotionFaultKind | None
    moving_as_commanded: bool

    def detail(self, kind: MotionFaultKind, window_s: float) -> str:
        if kind == "not_moving":
            return (f"commanded {self.commanded_mps:.3f} m/s, measured {self.measured_mps:.3f} m/s "
                    "over ground")
        return (f"{self.reject_rate:.0%} of the fixes gated out and a mean position innovation "
                f"of {self.mean_nis:.1f} (chi-square, 2 dof) in the last {window_s:g} s")


@dataclass(frozen=True)
class MotionFaultEvent:
    """A change of the fault: raised (``kind`` set) or cleared (``kind`` None)."""

    t_ns: int
    kind: MotionFaultKind | None
    detail: str


def _slope_speed(window: deque[FixSample]) -> float:
    """Speed over ground from the least-squares slope of the positions [m/s]."""
    t0 = window[0].t_ns
    ts = [(s.t_ns - t0) / NS_PER_S for s in window]
    tm = sum(ts) / len(ts)
    den = sum((t - tm) ** 2 for t in ts)
    if den <= 0.0:
        return 0.0
    nm = sum(s.north_m for s in window) / len(window)
    em = sum(s.east_m for s in window) / len(window)
    vn = sum((t - tm) * (s.north_m - nm) for t, s in zip(ts, window, strict=True)) / den
    ve = sum((t - tm) * (s.east_m - em) for t, s in zip(ts, window, strict=True)) / den
    return math.hypot(vn, ve)


class MotionMismatch:
    """The detector: ``on_fix`` per GNSS fix; ``kind``/``detail`` the fault now (None: none)."""

    def __init__(self, config: MismatchConfig) -> None:
        self.config = config
        self._window: deque[FixSample] = deque()
        self.kind: MotionFaultKind | None = None
        self.detail: str | None = None
        self.onsets = 0
        self._suspect_since: int | None = None
        self._clean_since: int | None = None
        self._proven_since: int | None = None
        self.last: Verdict | None = None

    def reset(self) -> None:
        """Forget the window (the filter re-initialised); a raised fault stays until cleared."""
        self._window.clear()
        self._suspect_since = self._clean_since = self._proven_since = None

    def _recent(self, window_s: float) -> list[FixSample] | None:
        """The fixes of the last ``window_s``, or None if too few or too short a span for a
        verdict."""
        c, w = self.config, self._window
        start = w[-1].t_ns - round(window_s * NS_PER_S)
        recent = [s for s in w if s.t_ns >= start]
        span = recent[-1].t_ns - recent[0].t_ns
        if len(recent) < c.min_samples or span < c.min_span_frac * window_s * NS_PER_S:
            return None
        return recent

    @staticmethod
    def _speeds(w: list[FixSample]) -> tuple[float, float]:
        """(commanded, measured) mean speeds of ``w`` [m/s]."""
        commanded = sum(s.commanded_mps for s in w) / len(w)
        sogs = [s.surge_over_ground_mps for s in w if s.surge_over_ground_mps is not None]
        measured = sum(sogs) / len(sogs) if len(sogs) == len(w) else _slope_speed(w)
        return commanded, measured

    def verdict(self) -> Verdict | None:
        """The evidence of the window now, or None if it is too short for one."""
        c = self.config
        w = self._recent(c.window_s) if self._window else None
        if w is None:
            return None
        n = len(w)
        commanded, measured = self._speeds(w)
        reject_rate = sum(s.rejected for s in w) / n
        finite = [s.nis for s in w if math.isfinite(s.nis)]
        mean_nis = sum(finite) / len(finite) if finite else math.inf
        commanding = commanded >= c.min_commanded_speed_mps
        still = commanding and measured < c.moving_ratio * commanded
        if not commanding:
            slow = self._recent(c.slow_window_s)
            if slow is not None:
                slow_cmd, slow_meas = self._speeds(slow)
                if slow_cmd >= c.min_slow_speed_mps and slow_meas < c.moving_ratio * slow_cmd:
                    still, commanded, measured = True, slow_cmd, slow_meas
        suspect: MotionFaultKind | None = None
        if still:
            suspect = "not_moving"
        elif ((reject_rate >= c.max_reject_rate or mean_nis > c.max_mean_nis)
              and (not commanding or measured < c.lost_thrust_ratio * commanded)):
            suspect = "not_as_modelled"
        return Verdict(commanded, measured, reject_rate, mean_nis, suspect,
                       moving_as_commanded=commanding and not still and suspect is None)

    def on_fix(self, sample: FixSample) -> MotionFaultEvent | None:
        """Take one fix's evidence; the fault's change it causes, if any."""
        c = self.config
        if not c.enabled:
            return None
        w = self._window
        if w and sample.t_ns < w[-1].t_ns:
            self.reset()  # time went back: a new run
        w.append(sample)
        horizon = sample.t_ns - round(max(c.window_s, c.slow_window_s) * NS_PER_S)
        while w and w[0].t_ns < horizon:
            w.popleft()
        v = self.verdict()
        self.last = v
        if v is None:
            return None
        t = sample.t_ns
        if v.suspect is not None:
            self._clean_since = self._proven_since = None
            if self._suspect_since is None:
                self._suspect_since = t
            if self.kind is None and t - self._suspect_since >= c.onset_s * NS_PER_S:
                self.kind, self.detail = v.suspect, v.detail(v.suspect, c.window_s)
                self.onsets += 1
                return MotionFaultEvent(t, self.kind, self.detail)
            if self.kind is not None and v.suspect == self.kind:
                self.detail = v.detail(v.suspect, c.window_s)  # the latest figures
            return None
        self._suspect_since = None
        if self._clean_since is None:
            self._clean_since = t
        if v.moving_as_commanded:
            if self._proven_since is None:
                self._proven_since = t
        else:
            self._proven_since = None
        if self.kind is None:
            return None
        proven = self._proven_since is not None and t - self._proven_since >= c.clear_s * NS_PER_S
        idle = t - self._clean_since >= c.idle_clear_s * NS_PER_S
        if not (proven or idle):
            return None
        was = self.kind
        self.kind = self.detail = None
        why = ("the vessel moves as commanded again" if proven else
               f"no disagreement for {c.idle_clear_s:g} s (little or no thrust commanded)")
        return MotionFaultEvent(t, None, f"{was} cleared: {why}")
