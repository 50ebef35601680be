"""``seaway report`` across a step of the boat's wall clock that the recorder said
(``seaway_recorder.clock_bridge``): a forward step is bridged, and the metrics are those of the
same run recorded without it; a recording with no word of the step is refused as before, naming it.

The recording is the replay golden (``tests/replay/data/lake-30s.mcap``) as a real-time run records
it, with everything logged before the middle of the mission put on a clock 56.9 years behind (a
boat booted at 1970 until GPS time set it): its log times and every wall time in its messages.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader
from seaway.contract.messages import EnergyBudget, PeriodDone, Refusals
from seaway.recording import reader
from seaway_recorder import clock_bridge, report, schemas

from tests.unit.recorder.rewrite import rewritten

GOLDEN = Path(__file__).resolve().parents[2] / "replay" / "data" / "lake-30s.mcap"
BEHIND_NS = 1_796_000_000_000_000_000  # from 2026-12 back to 1970-01-05
T = 1_000_000_000


def stepped(path: Path, behind_ns: int, say_step: bool, step_back: bool = False) -> None:
    """The golden as a real-time run would record it (its simulated stamps put on its wall clock,
    the log times), with what was logged before its middle on a clock ``behind_ns`` behind (or,
    ``step_back``, what was logged from its middle on: the clock stepped back). ``say_step``: with
    the recorder's record of the step."""
    with open(GOLDEN, "rb") as fh:
        stats = make_reader(fh).get_summary().statistics
    start = stats.message_start_time
    middle = (start + stats.message_end_time) // 2

    def each(_c, m):
        on_old = (m.log_time >= middle) if step_back else (m.log_time < middle)
        d = json.loads(m.data)
        clock_bridge._shift(d, 2**63, start - (behind_ns if on_old else 0))  # every wall time
        return m.log_time - (behind_ns if on_old else 0), json.dumps(d).encode(), m.publish_time

    def say(w) -> None:
        sid = w.register_schema(schemas.CLOCK_STEP_SCHEMA_NAME, "jsonschema",
                                json.dumps(schemas.CLOCK_STEP_SCHEMA).encode())
        cid = w.register_channel(schemas.CLOCK_STEP_TOPIC, "json", sid, {"role": "recorder"})
        seen = middle + 50_000_000 - (behind_ns if step_back else 0)
        step = -behind_ns if step_back else behind_ns
        w.add_message(cid, seen, json.dumps({"stamp_ns": seen, "step_ns": step}).encode(), seen, 0)

    rewritten(GOLDEN, path, each, say if say_step else None)


def done(stamp_ns: int) -> PeriodDone:
    return PeriodDone.model_validate({"stamp_ns": stamp_ns, "service": "sim", "period_ns": T,
                                      "episode": 0, "seq": 1})


def doc_of(path: Path, tmp: Path, capsys) -> dict[str, Any]:
    assert report.main([str(path), "--no-plots", "--json", "--out", str(tmp / "r")]) == 0
    return json.loads(capsys.readouterr().out)


def test_a_forward_step_said_by_the_recorder_is_bridged(tmp_path: Path, capsys) -> None:
    unstepped = tmp_path / "unstepped.mcap"
    stepped(unstepped, 0, say_step=False)
    original = doc_of(unstepped, tmp_path, capsys)
    path = tmp_path / "stepped.mcap"
    stepped(path, BEHIND_NS, say_step=True)
    doc = doc_of(path, tmp_path, capsys)
    # The same integers once bridged: the same metrics, every one of them.
    assert doc["metrics"] == original["metrics"]
    assert doc["metrics"]["state_samples"] == 302 and doc["metrics"]["legs_completed"] == 1
    (step,) = doc["recording"]["clock_steps"]
    assert step["bridged"] and step["step_s"] == pytest.approx(BEHIND_NS / 1e9)
    assert any("stepped" in note for note in doc["recording"]["notes"])


def test_a_step_the_recording_does_not_say_is_refused_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "stepped.mcap"
    stepped(path, BEHIND_NS, say_step=False)
    with pytest.raises(ValueError, match="clock was stepped"):
        report.analyse([path])


def test_a_step_back_is_said_and_not_bridged(tmp_path: Path, capsys) -> None:
    path = tmp_path / "stepped.mcap"
    stepped(path, 2 * T, say_step=True, step_back=True)
    dec = report.read_for_report([path])[1]
    ((_, step, bridged),) = dec.clock_steps
    assert step == -2 * T and not bridged


def test_every_wall_time_before_the_step_moves_and_nothing_else() -> None:
    before, by = 10 * T, BEHIND_NS
    budget = EnergyBudget(stamp_ns=5 * T, mission_id="m1", active_leg=1, energy_used_j=1.0,
                          battery_stamp_ns=4 * T, home_x_m=0.0, home_y_m=0.0, policy="return",
                          decision="none")
    moved = clock_bridge.shifted(budget, before, by)
    assert (moved.stamp_ns, moved.battery_stamp_ns) == (5 * T + by, 4 * T + by)
    later = budget.model_copy(update={"stamp_ns": 11 * T})  # given on the new clock already
    assert clock_bridge.shifted(later, before, by).stamp_ns == 11 * T
    refusals = Refusals(stamp_ns=11 * T, identity="vehicle_io", total=1, overflow=0,
                        counts=[{"identity": "x", "action": "put", "key": "k", "count": 1,
                                 "last_ns": 3 * T}])
    assert clock_bridge.shifted(refusals, before, by).counts[0].last_ns == 3 * T + by  # nested
    period = done(2 * T)
    after = clock_bridge.shifted(period, before, by)
    assert after.stamp_ns == 2 * T + by and after.period_ns == T  # a duration stays


def test_only_forward_steps_are_bridged_the_earliest_first() -> None:
    dec = reader.Decoded()
    dec.by_suffix["x"] = [done(t) for t in (T, 5 * T, 9 * T)]
    dec.log_ns["x"] = [T, 5 * T, 9 * T]
    # Stepped +3 s between 1 s and 5 s (at 4.x s on the new clock), then back 1 s, then +3 s
    # between 5 s and 9 s (seen at 8.x s on the clock the first step set).
    steps = [clock_bridge.ClockStep(4 * T + 50, 3 * T), clock_bridge.ClockStep(6 * T, -T),
             clock_bridge.ClockStep(8 * T + 50, 3 * T)]
    bridged = clock_bridge.bridge(dec, steps)
    assert bridged == [steps[0], steps[2]]
    assert [m.stamp_ns for m in dec.get("x")] == [7 * T, 8 * T, 9 * T]
    assert dec.log_ns["x"] == [7 * T, 8 * T, 9 * T]


@pytest.mark.parametrize("data", [
    b"not json", b"[1, 2]", b'{"stamp_ns": 5}', b'{"stamp_ns": "5", "step_ns": 3000000000}',
    b'{"stamp_ns": true, "step_ns": 3000000000}', b'{"stamp_ns": -1, "step_ns": 3000000000}',
    b'{"stamp_ns": 5000000000, "step_ns": 1000}',  # under the least step the recorder says
    b'{"stamp_ns": 5000000000, "step_ns": 6000000000}',  # the old clock before 1970
    b'{"stamp_ns": 5000000000, "step_ns": -1180591620717411303424}',
])
def test_a_record_that_is_no_step_is_none(data: bytes) -> None:
    assert clock_bridge.step_of(data) is None


def test_records_that_are_no_step_are_counted_and_left_out(tmp_path: Path, capsys) -> None:
    """A damaged or forged record on the channel moves nothing: the report goes on over every
    sample, and says how many records it left out."""
    with open(GOLDEN, "rb") as fh:
        start = make_reader(fh).get_summary().statistics.message_start_time

    def each(_c, m):
        d = json.loads(m.data)
        clock_bridge._shift(d, 2**63, start)
        return m.log_time, json.dumps(d).encode(), m.publish_time

    def forged(w) -> None:
        sid = w.register_schema(schemas.CLOCK_STEP_SCHEMA_NAME, "jsonschema",
                                json.dumps(schemas.CLOCK_STEP_SCHEMA).encode())
        cid = w.register_channel(schemas.CLOCK_STEP_TOPIC, "json", sid, {"role": "recorder"})
        for k, data in enumerate((b"not json", b'{"stamp_ns": 5, "step_ns": 2}',
                                  b'{"stamp_ns": 1, "step_ns": 1180591620717411303424}')):
            w.add_message(cid, start + k, data, start + k, k)

    path = tmp_path / "forged.mcap"
    rewritten(GOLDEN, path, each, forged)
    doc = doc_of(path, tmp_path, capsys)
    assert doc["recording"]["undecodable_by_topic"] == {schemas.CLOCK_STEP_TOPIC: 3}
    assert doc["recording"]["clock_steps"] == []
    assert doc["metrics"]["state_samples"] == 302
