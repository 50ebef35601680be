"""Run information through the recorder (a scenario's files attached, read back) and replay's key
filter and pacing. Reading attachments alone: tests/unit/common/test_recording_runinfo.py."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from seaway.recording import runinfo
from seaway.recording.reader import RecordedMessage
from seaway.runtime.bus_raw import RawSample
from seaway.runtime.memory_bus import MemoryBus, MemoryHub
from seaway_recorder import attachments
from seaway_recorder.replay import KeyFilter, normalise, replay


def test_scenario_attachments_bring_the_vessel_and_data_files() -> None:
    atts, scen = attachments.scenario_attachments("paper-c5")
    names = [a.name for a in atts]
    assert names == ["scenario/paper-c5.toml", "scenario-data/data/condition5_grid.json",
                     "vessel/paper-sim.toml"]
    assert scen.name == "paper-c5"
    by = {a.name: a.data for a in atts}
    mission = runinfo.mission_from_attachments(by, None)
    assert mission.waypoints == ((0.0, 0.0), (8.0, 0.0), (5.13, 8.57))
    assert (mission.coa_radius_m, mission.task_power_w) == (1.0, 0.49)
    assert runinfo.vessel_from_attachments(by).alpha_w_per_n2 == pytest.approx(0.4364)
    assert runinfo.scenario_from_attachments(by).origin.lat_deg == scen.origin.lat_deg


def test_attach_roles(tmp_path: Path) -> None:
    f = tmp_path / "profile.toml"
    f.write_text("x = 1\n")
    assert attachments.parse_attach_arg(f"profile={f}").name == "profile/profile.toml"
    a = attachments.parse_attach_arg(str(f))
    assert (a.name, a.media_type, a.data) == ("config/profile.toml", "application/toml", b"x = 1\n")
    with pytest.raises(Exception, match="cannot attach"):
        attachments.parse_attach_arg(str(tmp_path / "missing.toml"))


def test_key_filter() -> None:
    assert normalise("sim/truth") == "seaway/*/sim/truth"
    everything = KeyFilter()
    assert everything("seaway/v1/sim/truth")
    assert not everything("foxglove/v1/sim-truth") and not everything("recorder/malformed")
    f = KeyFilter(exclude=["nav/state"])
    assert f("seaway/v1/sensors/gnss") and not f("seaway/v2/nav/state")
    f = KeyFilter(only=["seaway/v1/**"], exclude=["seaway/*/ctrl/*"])
    assert f("seaway/v1/nav/state") and not f("seaway/v2/nav/state") and not f("seaway/v1/ctrl/thrust")


def listening_bus() -> tuple[MemoryBus, list[RawSample]]:
    """A bus to replay on, and everything that appears on it (as another process would hear it)."""
    hub = MemoryHub()
    heard: list[RawSample] = []
    hub.bus().subscribe_raw("**", heard.append)
    return hub.bus(), heard


class FakeClock:
    """Time that moves only when the replay waits: sleeps are exact, so pacing is checkable."""

    def __init__(self) -> None:
        self.t = 100.0
        self.waits: list[float] = []

    def __call__(self) -> float:
        return self.t


class FakeStop(threading.Event):
    def __init__(self, clock: FakeClock) -> None:
        super().__init__()
        self.clock = clock

    def wait(self, timeout=None) -> bool:
        self.clock.waits.append(timeout)
        self.clock.t += timeout
        return False


def msg(topic: str, t_ns: int, data: bytes = b"{}") -> RecordedMessage:
    return RecordedMessage(topic, t_ns, t_ns, 0, data, "seaway.v1.X", "json",
                           {"zenoh_encoding": "application/json;seaway.v1.X"})


def test_replay_paces_by_log_time_divided_by_rate() -> None:
    clock = FakeClock()
    stop = FakeStop(clock)
    bus, heard = listening_bus()
    msgs = [msg("seaway/v/a", 1_000_000_000), msg("foxglove/v/a", 1_100_000_000),
            msg("seaway/v/b", 1_500_000_000, b"B"), msg("seaway/v/a", 3_000_000_000, b"A")]
    stats = replay(iter(msgs), bus, KeyFilter(), 2.0, stop, clock=clock)
    assert [(s.key, s.payload) for s in heard] == [("seaway/v/a", b"{}"), ("seaway/v/b", b"B"),
                                                   ("seaway/v/a", b"A")]
    assert clock.waits == pytest.approx([0.25, 0.75])  # (0.5 s, then 1.5 s more) / 2
    assert (stats.published, stats.skipped) == (3, 1)
    assert stats.elapsed_s == pytest.approx(1.0) and stats.recorded_span_s == pytest.approx(2.0)
    assert {s.encoding for s in heard} == {"application/json;seaway.v1.X"}


def test_replay_as_fast_as_possible_never_waits() -> None:
    clock = FakeClock()
    stop = FakeStop(clock)
    bus, heard = listening_bus()
    msgs = [msg("seaway/v/a", k * 1_000_000_000) for k in range(5)]
    stats = replay(iter(msgs), bus, KeyFilter(only=["seaway/v/a"]), None, stop, clock=clock)
    assert clock.waits == [] and stats.published == 5 and len(heard) == 5
