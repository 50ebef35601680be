"""RecordingWriter and recover on real MCAP files (no bus): channels, schemas, errors, rotation, repair."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import jsonschema
import pytest
from mcap.reader import make_reader
from seaway.contract import bundle, keys
from seaway.contract.messages import GnssFix, NavOrigin, PeriodDone, SimTruth, ThrustCommand
from seaway.recording.reader import iter_messages, open_paths, read_info
from seaway.recording.recover import recover
from seaway.vessel.frames import GeoOrigin
from seaway_recorder.core import AttachmentSpec, RecordingWriter
from seaway_recorder.node import KeptKeys, lockstep_exprs, recorded_suffixes
from seaway_recorder.schemas import foxglove_json_schema

from tests.unit.recorder.foxglove_check import foxglove_messages, t_ns

V = "v1"
ENC = "application/json;seaway.v1.SimTruth"


def truth(i: int) -> bytes:
    return SimTruth.make(stamp_ns=i * 100_000_000, u_mps=0.5, v_mps=0.0, r_radps=0.0, x_m=0.1 * i,
                         y_m=0.0, psi_rad=0.0, thrust_port_n=1.0, thrust_starboard_n=1.0,
                         energy_j=0.1 * i).encode()


def thrust(i: int) -> bytes:
    return ThrustCommand.make(stamp_ns=i, thrust_port_n=1.0, thrust_starboard_n=-1.0, seq=i).encode()


def read_all(path: Path) -> list[tuple[str, str, bytes, int]]:
    with open(path, "rb") as fh:
        return [(c.topic, s.name if s else "", bytes(m.data), m.sequence)
                for s, c, m in make_reader(fh).iter_messages(log_time_order=True)]


def test_bytes_unchanged_with_schemas_metadata_and_attachments(tmp_path: Path) -> None:
    att = AttachmentSpec("scenario/s.toml", "application/toml", b"name = 's'")
    w = RecordingWriter(tmp_path / "r.mcap", attachments=[att], metadata={"seaway.run": {"scenario": "s"}},
                        foxglove=False)
    w.open(0)
    for i in range(50):
        assert w.write(keys.SIM_TRUTH.key(V), truth(i), ENC, 1000 + i)
        assert w.write(keys.THRUST.key(V), thrust(i), "application/json", 1000 + i)
    files = w.close(2000)
    assert files == [str(tmp_path / "r.mcap")]
    got = read_all(tmp_path / "r.mcap")
    assert [d for t, _, d, _ in got if t.endswith("sim/truth")] == [truth(i) for i in range(50)]
    assert [d for t, _, d, _ in got if t.endswith("ctrl/thrust")] == [thrust(i) for i in range(50)]
    assert [q for t, _, _, q in got if t.endswith("sim/truth")] == list(range(1, 51))
    with open(tmp_path / "r.mcap", "rb") as fh:
        r = make_reader(fh)
        summary = r.get_summary()
        schemas = {s.name: json.loads(s.data) for s in summary.schemas.values()}
        assert set(schemas) == {"seaway.v1.SimTruth", "seaway.v1.ThrustCommand"}
        assert schemas["seaway.v1.SimTruth"] == foxglove_json_schema(SimTruth.json_schema())
        assert all(s.encoding == "jsonschema" for s in summary.schemas.values())
        assert {c.metadata["producer"] for c in summary.channels.values()} == {"sim", "controller"}
        assert [(a.name, a.data) for a in r.iter_attachments()] == [("scenario/s.toml", b"name = 's'")]
        meta = {m.name: m.metadata for m in r.iter_metadata()}
    assert meta["seaway.run"] == {"scenario": "s"}
    assert meta["seaway.recorder.summary"]["messages"] == "100"


def test_malformed_and_unregistered_samples_are_kept_and_counted(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "r.mcap", foxglove=False)
    w.open(0)
    bad = b'{"stamp_ns": 1, "u_mps": "fast"}'
    assert not w.write(keys.SIM_TRUTH.key(V), bad, ENC, 10)
    assert w.write("seaway/v1/custom/thing", b"\x00\x01raw", "zenoh/bytes", 11)
    assert w.write(keys.SIM_TRUTH.key(V), truth(1), ENC, 12)
    w.close(20)
    assert (w.stats.malformed, w.stats.unregistered, w.stats.messages) == (1, 1, 2)
    with open(tmp_path / "r.mcap", "rb") as fh:
        msgs = {c.topic: (s, c, m) for s, c, m in make_reader(fh).iter_messages()}
    s, c, m = msgs["recorder/malformed"]
    env = json.loads(m.data)
    jsonschema.validate(env, json.loads(s.data))
    assert base64.b64decode(env["payload_base64"]) == bad
    assert env["key"] == keys.SIM_TRUTH.key(V) and env["schema"] == "seaway.v1.SimTruth"
    assert "u_mps" in env["error"]
    s, c, m = msgs["seaway/v1/custom/thing"]
    assert s is None and c.schema_id == 0 and bytes(m.data) == b"\x00\x01raw"
    assert c.metadata["registered"] == "false"


def test_no_validate_stores_even_malformed_bytes_on_the_key(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "r.mcap", foxglove=False, validate=False)
    w.open(0)
    w.write(keys.THRUST.key(V), b"nonsense", "application/json", 1)
    w.close(2)
    assert w.stats.malformed == 0
    assert [(t, d) for t, _, d, _ in read_all(tmp_path / "r.mcap")] == [(keys.THRUST.key(V), b"nonsense")]


def test_location_fix_from_truth_needs_an_origin(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "r.mcap")
    w.open(0)
    w.write(keys.SIM_TRUTH.key(V), truth(0), ENC, 1)  # no origin yet: nothing derived
    w.write(keys.NAV_ORIGIN.key(V), NavOrigin.make(stamp_ns=0, lat_rad=0.8, lon_rad=0.1, alt_m=0).encode(),
            "application/json", 2)
    w.write(keys.SIM_TRUTH.key(V), truth(10), ENC, 3)  # x = 1 m north of the origin
    w.close(4)
    fixes = [(t, msg) for _, name, t, msg in foxglove_messages(tmp_path / "r.mcap")
             if name == "foxglove.LocationFix"]
    assert len(fixes) == 1
    lat, lon, _ = GeoOrigin(0.8, 0.1).to_geodetic(1.0, 0.0)
    log_time, fix = fixes[0]
    assert fix.latitude == pytest.approx(lat * 57.29577951308232)
    assert fix.longitude == pytest.approx(lon * 57.29577951308232)
    assert t_ns(fix.timestamp) == 1_000_000_000  # real time: the source's stamp, unchanged
    assert log_time == 3  # real time: the receive time


@pytest.mark.parametrize("fix", [
    {"stamp_ns": 2**63 - 1},  # a valid int64 stamp past 2106: a Foxglove Timestamp's uint32 seconds
    {"stamp_ns": 1, "horizontal_std_m": 1e300},  # its variance past a float
])
def test_a_sample_without_a_foxglove_view_is_recorded_and_the_next_still_are(tmp_path, fix) -> None:
    """The deriving is for the viewer; the message itself, and the ones after it, are what must
    be kept: a view that cannot be made is counted, and the recorder goes on."""
    w = RecordingWriter(tmp_path / "r.mcap")
    w.open(0)
    gnss = keys.GNSS.key(V)
    odd = GnssFix.make(**{"stamp_ns": 0, "lat_rad": 0.8, "lon_rad": 0.1, "alt_m": 0.0, "fix_type": 3,
                          **fix}).encode()
    good = GnssFix.make(stamp_ns=5, lat_rad=0.8, lon_rad=0.1, alt_m=0.0, fix_type=3).encode()
    assert w.write(gnss, odd, "application/json", 1) and w.write(gnss, good, "application/json", 2)
    w.close(3)
    assert (w.stats.underived, w.stats.derived) == (1, 1)
    assert [d for t, _, d, _ in read_all(tmp_path / "r.mcap") if t == gnss] == [odd, good]


def test_rotation_by_size_gives_whole_files_in_order(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "rec.mcap", max_bytes=20_000, compression="none", foxglove=False,
                        metadata={"seaway.run": {"k": "v"}})
    w.open(0)
    for i in range(600):
        w.write(keys.SIM_TRUTH.key(V), truth(i), ENC, i)
        if i % 20 == 19:
            w.flush()
            w.maybe_rotate(i)
    files = w.close(1000)
    assert len(files) >= 3
    assert [Path(f).name for f in files] == [f"rec-{k:03d}.mcap" for k in range(len(files))]
    paths = open_paths([tmp_path])
    assert [str(p) for p in paths] == files
    info = read_info(paths)
    assert info.message_count == 600
    assert [m.data for m in iter_messages(paths)] == [truth(i) for i in range(600)]
    for f in files:
        with open(f, "rb") as fh:
            meta = {m.name: m.metadata for m in make_reader(fh).iter_metadata()}
        assert meta["seaway.run"]["k"] == "v" and "file_index" in meta["seaway.run"]


def _write_flushed(path: Path, n: int, flush_every: int) -> None:
    w = RecordingWriter(path, foxglove=False, metadata={"seaway.run": {"a": "b"}},
                        attachments=[AttachmentSpec("vessel/x.toml", "application/toml", b"x = 1")])
    w.open(0)
    for i in range(n):
        w.write(keys.SIM_TRUTH.key(V), truth(i), ENC, i)
        if i % flush_every == flush_every - 1:
            w.flush()
    w.close(n)


@pytest.mark.parametrize("cut_fraction", [0.999, 0.9, 0.6, 0.35])
def test_recover_keeps_every_whole_chunk_of_a_truncated_file(tmp_path: Path, cut_fraction: float) -> None:
    src = tmp_path / "full.mcap"
    _write_flushed(src, 400, 25)  # 16 chunks of 25 messages
    data = src.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * cut_fraction)])
    fixed = tmp_path / "fixed.mcap"
    res = recover(cut, fixed)
    # A cut in the summary section leaves the data whole (data-end record read); any other cut does not.
    assert res.complete == (res.messages == 400)
    assert res.complete or res.reason
    got = [m.data for m in iter_messages([fixed])]
    # A prefix of whole chunks: a multiple of 25 messages, in order, and nothing invented.
    assert got == [truth(i) for i in range(len(got))]
    assert len(got) % 25 == 0 and res.messages == len(got)
    # At least everything that was wholly written before the cut point survives.
    with open(src, "rb") as fh:
        whole = sum(25 for ci in make_reader(fh).get_summary().chunk_indexes
                    if ci.chunk_start_offset + ci.chunk_length + 200 < len(data) * cut_fraction)
    assert len(got) >= whole
    with open(fixed, "rb") as fh:
        r = make_reader(fh)
        assert r.get_summary().statistics.message_count == len(got)
        assert [a.name for a in r.iter_attachments()] == ["vessel/x.toml"]
        meta = {m.name: m.metadata for m in r.iter_metadata()}
    assert meta["seaway.run"] == {"a": "b"}
    assert meta["seaway.recover"]["complete"] == str(res.complete).lower()


def test_recover_of_a_complete_file_keeps_everything(tmp_path: Path) -> None:
    src = tmp_path / "full.mcap"
    _write_flushed(src, 100, 30)
    res = recover(src, tmp_path / "same.mcap")
    assert res.complete and res.messages == 100
    assert [m.data for m in iter_messages([tmp_path / "same.mcap"])] == [truth(i) for i in range(100)]


def test_recover_refuses_what_is_not_mcap(tmp_path: Path) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"hello, this is not an mcap file at all")
    with pytest.raises(ValueError, match="not an MCAP file"):
        recover(bad, tmp_path / "out.mcap")
    with pytest.raises(ValueError, match="must differ"):
        recover(bad, bad)


def test_a_lockstep_bundle_unpacks_into_its_keys_and_a_bad_one_is_kept_as_malformed(
        tmp_path: Path) -> None:
    """What a recorder writes of a bundle (seaway.contract.bundle): its messages on their own keys'
    channels then its answer, bytes unchanged. One whose framing does not read goes whole to
    ``recorder/malformed``; a line of a key its member does not produce goes there alone and the
    rest is written, as the members take it; each says why, and the writer goes on."""
    done = PeriodDone(stamp_ns=0, service="sim", episode=0, seq=1, period_ns=100_000_000,
                      published={keys.SIM_TRUTH.suffix: [0]})
    key = keys.LOCKSTEP_SIM.key(V)
    good = bundle.encode(done.encode(), [(keys.SIM_TRUTH.suffix, truth(0))])
    w = RecordingWriter(tmp_path / "r.mcap", foxglove=False)
    w.open(0)
    parts = w.unpack(key, good, bundle.ENCODING, 1_000)
    assert [(k, d) for k, d, _ in parts] == [(keys.SIM_TRUTH.key(V), truth(0)), (key, done.encode())]
    for k, d, enc in parts:
        assert w.write(k, d, enc, 1_000)
    assert w.unpack(key, b"{}\n[broken", bundle.ENCODING, 2_000) == []
    foreign = bundle.encode(done.encode(), [(keys.THRUST.suffix, thrust(1)),
                                            (keys.SIM_TRUTH.suffix, truth(1))])
    parts = w.unpack(key, foreign, bundle.ENCODING, 2_000)
    assert [(k, d) for k, d, _ in parts] == [(keys.SIM_TRUTH.key(V), truth(1)), (key, done.encode())]
    assert w.unpack(keys.SIM_TRUTH.key(V), truth(1), ENC, 3_000) == [(keys.SIM_TRUTH.key(V), truth(1), ENC)]
    w.close(4_000)
    got = read_all(tmp_path / "r.mcap")
    assert [(t, d) for t, _, d, _ in got if t != "recorder/malformed"] == [
        (keys.SIM_TRUTH.key(V), truth(0)), (key, done.encode())]
    errors = [json.loads(d) for t, _, d, _ in got if t == "recorder/malformed"]
    assert len(errors) == 2 and w.stats.malformed == 2
    assert "line 2" in errors[0]["error"]
    assert errors[1]["error"].startswith("line dropped, the rest written: lockstep bundle of sim "
                                         "carries 'ctrl/thrust', which it does not produce")
    assert {e["key"] for e in errors} == {key}


def test_a_foreign_line_does_not_keep_the_recorder_from_answering(tmp_path: Path) -> None:
    """A controller bundle with a line of the sim's key beside its command: the members drop that
    line and take the rest; the recorder writes the command, puts the line on the error channel
    and answers the period, so the sim does not wait on it for ever."""
    import time

    from seaway.recording.timebase import RecordingTime
    from seaway.runtime.lockstep import Period
    from seaway.runtime.lockstep_member import Member
    from seaway.runtime.lockstep_witness import LockstepWitness
    from seaway.runtime.memory_bus import MemoryHub
    from seaway_recorder.node import SampleQueue, drain

    P, exprs = 100_000_000, [f"seaway/{V}/**"]
    hub = MemoryHub()
    w = RecordingWriter(tmp_path / "r.mcap", compression="none",
                        time=RecordingTime(lockstep=True, epoch_ns=10**18))
    w.open(time.time_ns())
    queue = SampleQueue(10_000)
    witness = LockstepWitness(hub.bus(V), V, exprs)
    hub.bus(V).subscribe_raw(f"seaway/{V}/lockstep/*", queue.on_sample)
    answered: list[bytes] = []
    hub.bus(V).subscribe_raw(keys.lockstep_spec("recorder").key(V),
                             lambda s: answered.append(s.payload))
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    sim.answer(Period(0, 0), P, members=["controller", "recorder"])
    drain(w, queue, None, witness, KeptKeys(exprs))
    cmd = ThrustCommand.make(stamp_ns=0, thrust_port_n=5.0, thrust_starboard_n=5.0)
    ans = PeriodDone(stamp_ns=0, service="controller", episode=0, seq=7, period_ns=P,
                     published={keys.THRUST.suffix: [0]})
    payload = bundle.encode(ans.encode(), [(keys.THRUST.suffix, cmd.encode()),
                                           (keys.GNSS.suffix, b'{"stamp_ns":0}')])
    hub.bus(V).raw_publisher(keys.lockstep_spec("controller").key(V), bundle.ENCODING).put(payload)
    drain(w, queue, None, witness, KeptKeys(exprs))
    assert len(answered) == 1 and PeriodDone.decode(answered[0]).covers["controller"] == 7
    w.close(time.time_ns())
    got = read_all(tmp_path / "r.mcap")
    assert [d for t, _, d, _ in got if t == keys.THRUST.key(V)] == [cmd.encode()]
    errors = [json.loads(d)["error"] for t, _, d, _ in got if t == "recorder/malformed"]
    assert len(errors) == 1 and "carries 'sensors/gnss'" in errors[0]


def test_which_keys_a_recording_keeps_is_zenohs_own_matching() -> None:
    """``--key-expr`` narrows a recording; in lockstep the bundles are heard on ``lockstep/*`` for
    the protocol, and of the messages they carry only the kept keys are written."""
    kept = KeptKeys([f"seaway/{V}/nav/**", "seaway/*/ctrl/thrust"])
    assert kept(keys.NAV_STATE.key(V)) and kept(keys.THRUST.key("other"))
    assert not kept(keys.SIM_TRUTH.key(V)) and not kept(keys.NAV_STATE.key("other"))
    assert recorded_suffixes([f"seaway/{V}/nav/**"], V) == {"nav/state", "nav/origin", "nav/reset"}
    assert lockstep_exprs([f"seaway/{V}/**"], V) == [f"seaway/{V}/**"]
    assert lockstep_exprs([f"seaway/{V}/nav/**"], V) == [f"seaway/{V}/nav/**", f"seaway/{V}/lockstep/*"]
