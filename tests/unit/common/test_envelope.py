"""A vessel's envelope (seaway.vessel.envelope): where a state stops being a boat's."""

from __future__ import annotations

import math

import pytest
from seaway.vessel.envelope import MAX_SPEED_MPS, MAX_YAW_RATE_RADPS, envelope
from seaway.vessel.model import load_vessel


def test_the_envelope_scales_with_the_vessels_terminal_speed_and_has_absolute_caps() -> None:
    paper = load_vessel("paper-sim")
    e = envelope(paper)
    # Five times the terminal speed under full thrust on both sides: 2 T_max / min(X_u, Y_v).
    assert e.speed_mps == pytest.approx(5 * 2 * paper.thrust_max_n / min(paper.xu_kgps, paper.yv_kgps))
    assert e.speed_mps < MAX_SPEED_MPS and e.yaw_rate_radps <= MAX_YAW_RATE_RADPS
    light = paper.model_copy(update={"xu_kgps": 0.01, "yv_kgps": 0.01, "nr_kgm2ps": 0.001})
    assert envelope(light).speed_mps == MAX_SPEED_MPS  # a tiny identified damping
    assert envelope(light).yaw_rate_radps == MAX_YAW_RATE_RADPS


@pytest.mark.parametrize(("u", "v", "r", "absurd"), [
    (0.5, 0.1, 0.2, False), (-0.5, 0.0, -1.0, False),
    (9e27, -5e27, 1e28, True), (0.0, 4.0, 0.0, True), (0.1, 0.0, 7.0, True),
    (math.nan, 0.0, 0.0, True), (0.0, 0.0, math.inf, True),
])
def test_a_state_past_the_envelope_is_named_absurd(u: float, v: float, r: float, absurd: bool) -> None:
    why = envelope(load_vessel("paper-sim")).absurd(u, v, r)
    assert (why is not None) == absurd, why
