"""``seaway bench restart`` on a small file: the file it makes is a killed recorder's (no summary,
a chunk per flush interval), both reads find the same last 10.5 s, and its figures hang together.
No timing is asserted here; the figures are the bench's (docs/results.md)."""

from __future__ import annotations

from pathlib import Path

from seaway.recording.tail import tail_of
from seaway_lab.bench import restart


def test_the_bench_file_is_a_killed_recorders_and_both_reads_agree(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    n, last_ns = restart.make_killed_recording(path, hours=0.01, rate_msg_s=190.0)
    assert n == 6840 and last_ns == restart.START_NS + (n - 1) * round(1e9 / 190.0)
    assert not path.read_bytes().endswith(b"\x89MCAP0\r\n")  # no footer: as a kill leaves it
    since_ns = last_ns - restart.SINCE_BEFORE_END_NS
    expected = restart.read_everything(path, since_ns)
    assert len(expected) == 1995  # 10.5 s at 190/s, each message numbered
    tail = tail_of(path, since_ns)
    assert tail.messages == expected and tail.last_log_ns == last_ns
    assert len(restart.read_everything(path, 0)) == n  # every message distinct, none lost


def test_the_figures_hang_together() -> None:
    res = restart.run(["--hours", "0.005", "--repeat", "2"])
    fig = {f.name: f.value for f in res.figures}
    assert fig["messages"] == 3420 and fig["tail_messages"] == 1995
    assert fig["baseline_over_tail"] == fig["baseline_s"] / fig["tail_median_s"]
    assert fig["tail_p99_s"] >= fig["tail_median_s"] > 0
    target = next(f for f in res.figures if f.name == "hours_within_ready_timeout")
    assert target.ok == (target.value >= restart.TARGET_HOURS)
