"""``seaway bench soak``'s memory trend (``steady_trend``): a least-squares line through the samples
after the warm-up, so a one-off warm-up step does not count as growth and a steady leak does."""

from __future__ import annotations

import pytest
from seaway_lab.bench.soak import steady_trend

MB = 1_000_000


def series(rss_mb, dt_s: float = 5.0) -> list[tuple[float, int]]:
    """``(t_s, rss_bytes)`` every ``dt_s`` from the RSS values [MB]."""
    return [(i * dt_s, round(mb * MB)) for i, mb in enumerate(rss_mb)]


def test_a_warm_up_step_then_flat_is_no_steady_growth() -> None:
    # 124 -> 140 MB over the first 40 s, then flat for the rest of a 300 s run
    rss = [124 + 2 * i for i in range(9)] + [140.0] * 52
    start_to_end_pct = 100 * (rss[-1] - rss[0]) / rss[0]
    assert start_to_end_pct > 5  # what the start -> end comparison says
    growth_pct, slope_mb_per_h = steady_trend(series(rss))
    assert growth_pct == pytest.approx(0.0, abs=1e-6)
    assert slope_mb_per_h == pytest.approx(0.0, abs=1e-6)


def test_a_steady_leak_shows_as_growth_and_slope() -> None:
    # 100 MB rising 36 MB/h (10 kB/s) from the start: the steady part is 200 s of a 300 s run
    samples = [(t, int(100 * MB + 10_000 * t)) for t in range(0, 301, 5)]
    growth_pct, slope_mb_per_h = steady_trend(samples)
    assert slope_mb_per_h == pytest.approx(36.0, rel=1e-6)
    at_100_s = 100 * MB + 10_000 * 100
    assert growth_pct == pytest.approx(100 * 10_000 * 200 / at_100_s, rel=1e-6)


def test_the_line_averages_out_noise_a_two_point_comparison_would_not() -> None:
    # flat at 100 MB with the last sample 6 MB high: start -> end says 6 %, the line far less
    rss = [100.0] * 60 + [106.0]
    growth_pct, _ = steady_trend(series(rss))
    assert 0 < growth_pct < 1.0


def test_the_steady_part_begins_a_third_into_the_run() -> None:
    # steep before 100 s of 300 s, flat after: only the flat part counts
    samples = [(t, int((50 + (t if t < 100 else 100)) * MB)) for t in range(0, 301, 10)]
    growth_pct, _ = steady_trend(samples)
    assert growth_pct == pytest.approx(0.0, abs=1e-6)
    # from the start instead, the warm-up ramp counts
    growth_all, _ = steady_trend(samples, steady_from=0.0)
    assert growth_all > 5


def test_too_few_samples_give_no_figure() -> None:
    assert steady_trend([]) is None
    assert steady_trend(series([100.0, 101.0])) is None
    assert steady_trend(series([100.0, 100.0, 101.0])) is None  # 2 in the steady part
    assert steady_trend([(0.0, 1), (0.0, 2), (0.0, 3)]) is None  # no time span
