"""The shared rate-limited log (``seaway.runtime.ratelog``): a flood of one kind of line becomes a
line now and then with a count; keys are independent and their table is bounded. Time passed in."""

from __future__ import annotations

import logging

import pytest
from seaway.runtime.ratelog import RateLimitedLog

S = 1_000_000_000
LOGGER = "test.ratelog"


def lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER]


def test_a_flood_of_one_kind_is_one_line_per_interval_with_the_count(caplog) -> None:
    caplog.set_level(logging.INFO, LOGGER)
    rl = RateLimitedLog(logging.getLogger(LOGGER), every_s=5.0)
    # 10,000 malformed samples a second for 3 s: the first is written, the rest counted.
    for i in range(30_000):
        rl.warning(("malformed", "k"), "dropped malformed payload on %s", "k", now_ns=i * S // 10_000)
    assert lines(caplog) == ["dropped malformed payload on k"]
    assert rl.held(("malformed", "k")) == 29_999 and rl.suppressed_total == 29_999
    # After the interval the next one is written, saying how many were held back meanwhile.
    rl.warning(("malformed", "k"), "dropped malformed payload on %s", "k", now_ns=8 * S)
    assert lines(caplog)[-1] == ("dropped malformed payload on k (29999 more like it since the "
                                 "last report)")
    assert rl.held(("malformed", "k")) == 0


def test_keys_are_independent_and_levels_kept(caplog) -> None:
    caplog.set_level(logging.INFO, LOGGER)
    rl = RateLimitedLog(logging.getLogger(LOGGER), every_s=1.0)
    assert rl.warning("a", "first a", now_ns=0)
    assert rl.info("b", "first b", now_ns=0)
    assert not rl.warning("a", "second a", now_ns=S // 2)
    assert rl.warning("a", "third a", now_ns=S)  # exactly one interval later
    got = [(r.levelno, r.getMessage()) for r in caplog.records if r.name == LOGGER]
    assert got == [(logging.WARNING, "first a"), (logging.INFO, "first b"),
                   (logging.WARNING, "third a (1 more like it since the last report)")]


def test_the_key_table_is_bounded(caplog) -> None:
    """A flood of ever-new keys (junk on new key expressions) shares one budget past the bound."""
    caplog.set_level(logging.INFO, LOGGER)
    rl = RateLimitedLog(logging.getLogger(LOGGER), every_s=60.0, max_keys=3)
    for i in range(1000):
        rl.warning(("new key", i), "junk on key %d", i, now_ns=i)
    written = lines(caplog)
    assert written[:3] == ["junk on key 0", "junk on key 1", "junk on key 2"]
    assert len(written) == 4 and written[3].startswith("junk on key 3 (one report for every key")
    assert len(rl._last_ns) <= 4


def test_exception_lines_carry_the_traceback(caplog) -> None:
    caplog.set_level(logging.INFO, LOGGER)
    rl = RateLimitedLog(logging.getLogger(LOGGER))
    for _ in range(3):
        try:
            raise ValueError("math domain error")
        except ValueError:
            rl.exception("step", "control step failed", now_ns=0)
    recs = [r for r in caplog.records if r.name == LOGGER]
    assert len(recs) == 1 and recs[0].levelno == logging.ERROR and recs[0].exc_info is not None


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="every_s must be > 0"):
        RateLimitedLog(logging.getLogger(LOGGER), every_s=0)
