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
from collections.abc import Sequence
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


def _slope_speed(window: Sequence[FixSample]) -> float:
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


_FIXED_BITS = 1074
"""Every finite float is a whole multiple of 2**-1074 (the smallest subnormal's unit), so a sum kept
as an int in that unit is exact: adding a fix to a window and taking the oldest out leaves no
rounding behind, however long the run, and a mean is the exact sum, rounded once."""


def _fixed(x: float) -> int:
    """``x`` (finite) in units of 2**-1074, exactly."""
    n, d = x.as_integer_ratio()  # d is a power of two, at most 2**1074
    return n << (_FIXED_BITS + 1 - d.bit_length())


def _mean(total: int, n: int) -> float:
    """The mean of ``n`` values whose exact sum in units of 2**-1074 is ``total``, rounded once."""
    return total / (n << _FIXED_BITS)  # int / int: correctly rounded


_Terms = tuple[int, int | None, int | None, bool]


def _terms(s: FixSample) -> _Terms:
    """What a fix adds to a window's sums (``_Window``), in units of 2**-1074: its commanded speed,
    its surge over ground and its NIS (None: it has none), and whether it was rejected. Converted
    once per fix, however many windows it enters and leaves."""
    return (_fixed(s.commanded_mps),
            None if s.surge_over_ground_mps is None else _fixed(s.surge_over_ground_mps),
            _fixed(s.nis) if math.isfinite(s.nis) else None, s.rejected)


class _Window:
    """The fixes of the last ``span_ns`` before the newest (inclusive), with the sums a verdict
    needs kept as fixes come and go, so that a verdict costs the same however many fixes it spans.
    """

    def __init__(self, span_s: float) -> None:
        self.span_ns = round(span_s * NS_PER_S)
        self.fixes: deque[FixSample] = deque()
        self._terms: deque[_Terms] = deque()  # each fix's ``_terms``, beside it
        self.clear()

    def clear(self) -> None:
        self.fixes.clear()
        self._terms.clear()
        self.commanded = self.sog = self.nis = 0  # exact sums, units of 2**-1074 (_fixed)
        self.n_sog = self.n_nis = self.rejected = 0

    def _add(self, terms: _Terms, sign: int) -> None:
        commanded, sog, nis, rejected = terms
        self.commanded += sign * commanded
        if sog is not None:
            self.sog += sign * sog
            self.n_sog += sign
        if nis is not None:
            self.nis += sign * nis
            self.n_nis += sign
        self.rejected += sign * rejected

    def push(self, s: FixSample, terms: _Terms | None = None) -> None:
        """Add the newest fix (``terms``: its ``_terms``, if already known) and drop those older
        than ``span_ns`` before it."""
        w = self.fixes
        if terms is None:
            terms = _terms(s)
        w.append(s)
        self._terms.append(terms)
        self._add(terms, 1)
        start = s.t_ns - self.span_ns
        while w[0].t_ns < start:
            w.popleft()
            self._add(self._terms.popleft(), -1)

    def speeds(self) -> tuple[float, float]:
        """(commanded, measured) mean speeds [m/s]: the fixes' velocity over ground when every
        fix has one, else the slope of their positions."""
        n = len(self.fixes)
        measured = _mean(self.sog, n) if self.n_sog == n else _slope_speed(self.fixes)
        return _mean(self.commanded, n), measured


class MotionMismatch:
    """The detector: ``on_fix`` per GNSS fix; ``kind``/``detail`` the fault now (None: none)."""

    def __init__(self, config: MismatchConfig) -> None:
        self.config = config
        self._fast = _Window(config.window_s)
        self._slow = _Window(config.slow_window_s)
        self.kind: MotionFaultKind | None = None
        self.detail: str | None = None
        self.onsets = 0
        self._suspect_since: int | None = None
        self._clean_since: int | None = None
        self._proven_since: int | None = None
        self.last: Verdict | None = None

    def reset(self) -> None:
        """Forget the window (the filter re-initialised); a raised fault stays until cleared."""
        self._fast.clear()
        self._slow.clear()
        self._suspect_since = self._clean_since = self._proven_since = None

    def _judged(self, w: _Window, window_s: float) -> bool:
        """Whether ``w`` holds enough fixes over a long enough span for a verdict."""
        f = w.fixes
        return (len(f) >= self.config.min_samples
                and f[-1].t_ns - f[0].t_ns >= self.config.min_span_frac * window_s * NS_PER_S)

    def verdict(self) -> Verdict | None:
        """The evidence of the window now, or None if it is too short for one."""
        c, w = self.config, self._fast
        if not w.fixes or not self._judged(w, c.window_s):
            return None
        n = len(w.fixes)
        commanded, measured = w.speeds()
        reject_rate = w.rejected / n
        mean_nis = _mean(w.nis, w.n_nis) if w.n_nis else math.inf
        commanding = commanded >= c.min_commanded_speed_mps
        still = commanding and measured < c.moving_ratio * commanded
        if not commanding and self._judged(self._slow, c.slow_window_s):
            slow_cmd, slow_meas = self._slow.speeds()
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
        w = self._fast.fixes
        if w and sample.t_ns < w[-1].t_ns:
            self.reset()  # time went back: a new run
        terms = _terms(sample)
        self._fast.push(sample, terms)
        self._slow.push(sample, terms)
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
