"""``seaway export ros2 RECORDING OUT``: a Seaway recording as an MCAP that rosbag2 plays.

OUT is a rosbag2 bag in one MCAP file: one CDR channel per topic of the ROS 2 face
(``seaway.ros2.face``) for each vessel recorded: ``/<vessel>/odom``, ``/<vessel>/gnss/fix``, ... in
the ROS 2 types, frames and units the live face publishes, one message for each Seaway message
it comes from, at the same log and publish times. It follows rosbag2_storage_mcap's layout:
profile ``ros2``; each channel with message encoding ``cdr``, a ``ros2msg`` schema (the type's
``.msg`` text and its dependencies, ``seaway.ros2.types.msg_definition``) and the channel metadata
``offered_qos_profiles`` (ROS's default profile: reliable, volatile, keep last 10) and
``topic_type_hash``; and the metadata record ``rosbag2`` (``serialized_metadata``, the bag's
metadata as rosbag2 writes it, and ``ROS_DISTRO``).

Everything else the recording held (its JSON channels, attachments, metadata), unchanged, goes to
a second file beside OUT, ``<OUT's stem>.seaway.mcap`` (:func:`companion_path`), not into OUT:
rosbag2's reader refuses a bag whose topics have different serialization formats
(``SequentialReader::open``, "All topics must have the same serialization format") and a channel
without a schema (``MCAPStorage::read_metadata``), so one JSON channel in OUT would make the whole
bag unplayable; ``rosbags`` refuses the ``jsonschema`` schemas too. ``--only-ros2`` skips it.

``/diagnostics`` is live only: health is liveliness, which a recording does not hold.
"""

from __future__ import annotations

import argparse
import heapq
import json
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import MessageError
from seaway.recording import reader, runinfo
from seaway.ros2 import cdr, face, rmw
from seaway.ros2 import types as rt
from seaway.vessel.model import VesselParams, load_vessel

PROFILE = "ros2"
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
STORAGE_ID = "mcap"
ROS_DISTRO = "jazzy"
"""The distribution whose message definitions and type hashes ``seaway.ros2.types`` follows."""
BAG_METADATA_RECORD = "rosbag2"
BAG_METADATA_VERSION = 8
"""rosbag2's ``BagMetadata`` version written: 8 has ``ros_distro`` and reads each topic's QoS as
the string the channel metadata also holds (version 9 wants a YAML list there)."""
COMPANION_SUFFIX = ".seaway.mcap"
_INFINITE = "    sec: 9223372036\n    nsec: 854775807\n"
DEFAULT_QOS_YAML = ("- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n"
                    f"  deadline:\n{_INFINITE}  lifespan:\n{_INFINITE}  liveliness: 1\n"
                    f"  liveliness_lease_duration:\n{_INFINITE}"
                    "  avoid_ros_namespace_conventions: false\n")
"""rosbag2's ``offered_qos_profiles`` of one publisher with ROS's default QoS (numeric enums:
keep last, reliable, volatile, automatic; durations infinite), the form every rosbag2 reads."""


@dataclass
class ExportStats:
    copied: int = 0
    converted: dict[str, int] | None = None
    dropped: dict[str, int] | None = None
    companion: Path | None = None
    first_ns: int | None = None
    last_ns: int | None = None


def companion_path(out: Path) -> Path:
    """Where the export keeps what is not ROS 2: ``run.mcap`` -> ``run.seaway.mcap``."""
    return out.with_name((out.name[:-5] if out.name.endswith(".mcap") else out.name)
                         + COMPANION_SUFFIX)


def bag_metadata(out: Path, stats: ExportStats, topics: dict[str, str]) -> str:
    """rosbag2's ``serialized_metadata`` of OUT (``YAML::convert<BagMetadata>::encode``'s fields),
    as JSON, which is YAML too. ``topics``: topic -> ROS type."""
    assert stats.converted is not None
    first = stats.first_ns or 0
    duration = {"nanoseconds": (stats.last_ns or first) - first}
    start = {"nanoseconds_since_epoch": first}
    count = sum(stats.converted.values())
    return json.dumps({
        "version": BAG_METADATA_VERSION, "storage_identifier": STORAGE_ID,
        "duration": duration, "starting_time": start, "message_count": count,
        "topics_with_message_count": [
            {"topic_metadata": {"name": t, "type": ty, "serialization_format": MESSAGE_ENCODING,
                                "offered_qos_profiles": DEFAULT_QOS_YAML,
                                "type_description_hash": rt.type_hash(ty)},
             "message_count": stats.converted.get(t, 0)} for t, ty in sorted(topics.items())],
        "compression_format": "", "compression_mode": "",
        "relative_file_paths": [out.name],
        "files": [{"path": out.name, "starting_time": start, "duration": duration,
                   "message_count": count}],
        "custom_data": {}, "ros_distro": ROS_DISTRO,
    }, indent=1)


@dataclass(frozen=True)
class _Raw:
    log_time: int
    publish_time: int
    sequence: int
    channel: Any
    schema: Any
    data: bytes


def _iter_raw(files: Sequence[Path]) -> Iterator[_Raw]:
    """Every message of the files in log-time order; UnreadableRecordingError where one is
    damaged (``reader.iter_file_records``)."""

    def one(path: Path) -> Iterator[_Raw]:
        for schema, channel, msg in reader.iter_file_records(path):
            yield _Raw(msg.log_time, msg.publish_time, msg.sequence, channel, schema,
                       bytes(msg.data))

    yield from heapq.merge(*(one(f) for f in files), key=lambda r: r.log_time)


def vessel_of(info: reader.RecordingInfo, vessel_file: str | None) -> VesselParams:
    """The vessel the thrust's moment is computed with: ``vessel_file``, else the recording's."""
    if vessel_file is not None:
        return load_vessel(vessel_file)
    found = runinfo.vessel_from_attachments(info.attachments)
    if found is not None:
        return found
    run = runinfo.run_from_attachments(info.attachments)
    if run is not None:
        return load_vessel(run.model_vessel_file)
    raise ConfigError("the recording names no vessel file (no vessel/* or run/run.json "
                      "attachment): give --vessel-file")


def export(recording: Sequence[Path], out: Path, vessel: VesselParams | None = None,
           vessel_file: str | None = None, only_ros2: bool = False) -> ExportStats:
    """Write ``out`` (the ROS 2 bag) and, unless ``only_ros2``, ``companion_path(out)`` (the rest,
    unchanged) from the recording's files (module docstring). Where the recording cannot be read
    to its end (``reader.UnreadableRecordingError``, a damaged chunk), neither file is left: half a
    bag would pass for the whole recording."""
    files = reader.open_paths(recording)
    info = reader.read_info(files)
    params = vessel or vessel_of(info, vessel_file)
    companion = None if only_ros2 else companion_path(out)
    try:
        return _write(files, info, params, out, companion)
    except BaseException:
        for written in (out, companion):
            if written is not None:
                written.unlink(missing_ok=True)
        raise


def _write(files: list[Path], info: reader.RecordingInfo, params: VesselParams, out: Path,
           companion: Path | None) -> ExportStats:
    """``export``'s files written."""
    from mcap.writer import Writer

    stats = ExportStats(converted={}, dropped={})
    with open(out, "wb") as fh, (open(companion, "wb") if companion else _Nothing()) as cfh:
        w = Writer(fh)
        w.start(profile=PROFILE, library="seaway export ros2")
        rest = Writer(cfh) if companion else None
        if rest is not None:
            rest.start(profile="", library="seaway export ros2 (kept as recorded)")
        schemas: dict[Any, int] = {}
        channels: dict[Any, int] = {}
        ros_schemas: dict[str, int] = {}
        ros_channels: dict[str, int] = {}
        ros_types: dict[str, str] = {}

        def ros_channel(topic: str, type_name: str) -> int:
            if topic not in ros_channels:
                if type_name not in ros_schemas:
                    ros_schemas[type_name] = w.register_schema(
                        type_name, SCHEMA_ENCODING, rt.msg_definition(type_name).encode())
                ros_channels[topic] = w.register_channel(
                    topic, MESSAGE_ENCODING, ros_schemas[type_name],
                    {"offered_qos_profiles": DEFAULT_QOS_YAML,
                     "topic_type_hash": rt.type_hash(type_name)})
                ros_types[topic] = type_name
            return ros_channels[topic]

        for raw in _iter_raw(files):
            ch = raw.channel
            _convert(raw, params, ros_channel, w, stats)
            if rest is None:
                continue
            # A channel by what it is, not by its id: each file of a rotated series numbers its
            # channels itself, and one topic's are one channel here.
            schema_key = (None if raw.schema is None else
                          (raw.schema.name, raw.schema.encoding, bytes(raw.schema.data)))
            channel_key = (ch.topic, ch.message_encoding, schema_key,
                           tuple(sorted(ch.metadata.items())))
            if channel_key not in channels:
                sid = 0
                if schema_key is not None:
                    if schema_key not in schemas:
                        schemas[schema_key] = rest.register_schema(*schema_key)
                    sid = schemas[schema_key]
                channels[channel_key] = rest.register_channel(ch.topic, ch.message_encoding, sid,
                                                              dict(ch.metadata))
            rest.add_message(channels[channel_key], raw.log_time, raw.data, raw.publish_time,
                             raw.sequence)
            stats.copied += 1
        w.add_metadata(BAG_METADATA_RECORD, {
            "serialized_metadata": bag_metadata(out, stats, ros_types), "ROS_DISTRO": ROS_DISTRO})
        w.finish()
        if rest is not None:
            for name, data in info.attachments.items():
                rest.add_attachment(info.start_ns, info.start_ns, name, "application/octet-stream",
                                    data)
            for name, meta in info.metadata.items():
                rest.add_metadata(name, meta)
            rest.finish()
    stats.companion = companion
    return stats


class _Nothing:
    """A context that is no file (``--only-ros2`` writes no companion)."""

    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


def _convert(raw: _Raw, params: VesselParams, ros_channel: Any, w: Any, stats: ExportStats) -> None:
    spec = keys.spec_for_key(raw.channel.topic)
    topic = face.BY_SUFFIX.get(spec.suffix) if spec is not None else None
    if topic is None or spec is None or spec.message is None:
        return
    assert stats.converted is not None and stats.dropped is not None
    vessel = raw.channel.topic.split("/")[1]
    fq = rmw.qualify(f"/{rmw.ros_name(vessel)}", topic.name)
    try:
        msg = spec.message.decode(raw.data)
        type_name, value = face.ros_message(topic, msg, params)
        data = cdr.encode(type_name, value)
    except (MessageError, cdr.CdrError, ValueError):
        stats.dropped[fq] = stats.dropped.get(fq, 0) + 1
        return
    w.add_message(ros_channel(fq, type_name), raw.log_time, data, raw.publish_time, raw.sequence)
    stats.converted[fq] = stats.converted.get(fq, 0) + 1
    stats.first_ns = raw.log_time if stats.first_ns is None else min(stats.first_ns, raw.log_time)
    stats.last_ns = raw.log_time if stats.last_ns is None else max(stats.last_ns, raw.log_time)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="seaway export ros2", description=__doc__.split("\n\n")[0])
    ap.add_argument("recording", type=Path, nargs="+",
                    help="the recording: an .mcap file, a rotated series, or a run folder")
    ap.add_argument("out", type=Path, help="the MCAP file to write (a rosbag2 bag, CDR only); the "
                    f"rest of the recording goes beside it, <stem>{COMPANION_SUFFIX}")
    ap.add_argument("--vessel-file", default=None, metavar="NAME|PATH",
                    help="the vessel file for the thrust's yaw moment (default: the recording's)")
    ap.add_argument("--only-ros2", action="store_true",
                    help=f"write the ROS 2 bag alone, without <stem>{COMPANION_SUFFIX}")
    args = ap.parse_args(list(argv) if argv is not None else None)
    written = [args.out] + ([] if args.only_ros2 else [companion_path(args.out)])
    if any(o.resolve() == Path(r).resolve() for o in written for r in args.recording):
        print(f"seaway export ros2: {' or '.join(map(str, written))} would overwrite the "
              "recording; name another OUT", file=sys.stderr)
        return 2
    try:
        stats = export(args.recording, args.out, vessel_file=args.vessel_file,
                       only_ros2=args.only_ros2)
    except (ConfigError, FileNotFoundError) as err:
        print(f"seaway export ros2: {err}", file=sys.stderr)
        return 2
    except reader.UnreadableRecordingError as err:
        gone = " and ".join(str(o) for o in written if not o.exists())
        print(f"seaway export ros2: {err}" + (f"; {gone} not written (a part would pass for the "
                                              "whole recording)" if gone else ""), file=sys.stderr)
        return 2
    assert stats.converted is not None and stats.dropped is not None
    print(f"wrote {args.out}: {sum(stats.converted.values())} ROS 2 messages (CDR) on "
          f"{len(stats.converted)} topics"
          + "".join(f"\n  {t}: {n}" for t, n in sorted(stats.converted.items()))
          + (f"\n  dropped (not convertible): {stats.dropped}" if stats.dropped else "")
          + (f"\nwrote {stats.companion}: {stats.copied} messages kept as recorded, with the "
             "recording's attachments and metadata" if stats.companion else ""))
    return 0
