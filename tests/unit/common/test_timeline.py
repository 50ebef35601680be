"""``seaway.runtime.timeline``: off unless asked, bounded, and what is written reads back."""

from __future__ import annotations

from pathlib import Path

import pytest
from seaway.runtime import timeline


def test_off_unless_the_variable_names_a_folder(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(timeline.ENV_TRACE, raising=False)
    t = timeline.Timeline.from_env("sim")
    t.mark("sent", 0)
    assert t.marks is None and t.write() is None


def test_marks_read_back_per_service_first_mark_kept(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(timeline.ENV_TRACE, str(tmp_path / "tl"))
    t = timeline.Timeline.from_env("estimator")
    t.mark("heard", 100, "sim")
    t.mark("work", 100)
    t.mark("heard", 100, "sim")  # a repeat of the same answer: not a new arrival
    t.mark("sent", 100)
    path = t.write()
    assert path is not None and path.name.startswith("estimator-")
    marks = timeline.first_marks(timeline.read(tmp_path / "tl"))
    assert set(marks) == {("estimator", "heard", "sim"), ("estimator", "work", ""),
                          ("estimator", "sent", "")}
    heard, work, sent = (marks[("estimator", w, o)][100] for w, o in
                         (("heard", "sim"), ("work", ""), ("sent", "")))
    assert heard <= work <= sent
    assert heard == t.marks[0][0]  # the first one


def test_at_most_max_marks_are_kept(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(timeline, "MAX_MARKS", 5)
    t = timeline.Timeline("sim", tmp_path)
    for k in range(20):
        t.mark("sent", k)
    assert t.marks is not None and len(t.marks) == 5
