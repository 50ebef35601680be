"""``seaway report`` says which recorded messages it could not decode (they are in no figure), per
topic; and, where the truth was recorded but none of it decodes, that this is why its positions
and energy come from the estimate."""

from __future__ import annotations

import json
from pathlib import Path

from seaway.contract import keys
from seaway_recorder import report

from tests.unit.recorder.rewrite import rewritten

GOLDEN = Path(__file__).resolve().parents[2] / "replay" / "data" / "lake-30s.mcap"
TRUTH = keys.SIM_TRUTH.key("replay1")


def spoiled(path: Path, spoil: int | None) -> int:
    """The golden recording with ``spoil`` of its truth messages (None: all) replaced by JSON that
    is not a truth; how many truth messages it holds."""
    n = 0

    def each(c, m):
        nonlocal n
        data = bytes(m.data)
        if c.topic == TRUTH:
            if spoil is None or n < spoil:
                data = b'{"stamp_ns": %d, "hello": 1}' % m.log_time
            n += 1
        return m.log_time, data, m.publish_time

    rewritten(GOLDEN, path, each)
    return n


def test_truth_that_never_decodes_is_said_and_the_estimate_used(tmp_path: Path, capsys) -> None:
    path = tmp_path / "recording.mcap"
    n = spoiled(path, None)
    assert report.main([str(path), "--no-plots", "--json", "--out", str(tmp_path / "r")]) == 0
    out, err = capsys.readouterr()
    doc = json.loads(out)
    assert doc["recording"]["undecodable_by_topic"] == {TRUTH: n}
    assert doc["metrics"]["state_source"] == keys.NAV_STATE.suffix
    notes = doc["recording"]["notes"]
    per_topic, why = notes
    assert TRUTH in per_topic and f"{n}" in per_topic
    assert keys.SIM_TRUTH.suffix in why and keys.NAV_STATE.suffix in why
    assert err.count("NOTE:") == len(notes)
    assert report.main([str(path), "--no-plots", "--out", str(tmp_path / "r")]) == 0
    table = capsys.readouterr().out
    assert all(f"NOTE: {line}" in table for line in notes)


def test_a_few_undecodable_truths_are_counted_and_truth_still_used(tmp_path: Path, capsys) -> None:
    path = tmp_path / "recording.mcap"
    spoiled(path, 3)
    assert report.main([str(path), "--no-plots", "--json", "--out", str(tmp_path / "r")]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["recording"]["undecodable_by_topic"] == {TRUTH: 3}
    assert doc["metrics"]["state_source"] == keys.SIM_TRUTH.suffix
    (line,) = doc["recording"]["notes"]
    assert TRUTH in line and "3" in line
