"""Robot logs: ROS 2 bags (a folder with metadata.yaml; sqlite3 or MCAP storage) and MCAP files.

Read with `rosbags` (no ROS installation needed), the optional extra `robotlogs`. A source
name is a topic and a field path, `/joint_states.position[1]`, `/cmd.data`,
`/odom.twist.twist.linear.x` (0-based index into an array field), or by a joint's name where
the message names its entries (`sensor_msgs/JointState`: `/joint_states.position[motor]`
takes the entry of `name` 'motor' in every message, whatever the order). Each topic has its own
clock and rate; `merged` puts every signal on one uniform grid (resample.merge_streams).
The time base, the source of `t`: `header`, a message's header stamp (its log time where the
message has no header; the default) or `log`, the time the logger received it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from .errors import RecordingError, listing, quote
from .resample import merge_streams
from .validate import Context, check_time

EXTRA = "robotlogs"
CLOCKS = ("header", "log")
_SOURCE = re.compile(r"(/[^.\s\[\]]*)\.(.+)")
_FIELD = re.compile(r"\s*([A-Za-z_]\w*)\s*(?:\[\s*([0-9]+|[A-Za-z_][\w/.-]*)\s*\])?\s*")
FORMS = "/TOPIC.FIELD, /TOPIC.FIELD.SUBFIELD, /TOPIC.FIELD[i] (0-based) or /TOPIC.FIELD[JOINT_NAME]"


def is_log_folder(path: Path) -> bool:
    """A ROS 2 bag: a folder holding metadata.yaml beside its storage files."""
    return path.is_dir() and (path / "metadata.yaml").is_file()


def _rosbags() -> Any:
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise RecordingError(
            f"reading ROS 2 bags and MCAP files needs the optional extra '{EXTRA}': pip install 'mjjoint[{EXTRA}]'"
        ) from None
    return AnyReader, get_typestore(Stores.LATEST)


@dataclass(frozen=True)
class FieldPick:
    """A parsed source name: the topic and the field path, each step with an optional index."""

    topic: str
    steps: tuple[tuple[str, int | str | None], ...]  # field, and an index or an entry's name

    def value(self, msg: Any, what: str) -> float:
        x, walked = msg, self.topic
        for name, index in self.steps:
            if not hasattr(x, name):
                fields = getattr(type(x), "__dataclass_fields__", {})
                raise RecordingError(f"{what}: {quote(walked)} has no field {quote(name)}; fields: {listing(fields)}")
            parent, x, walked = x, getattr(x, name), f"{walked}.{name}"
            if isinstance(index, str):
                names = list(getattr(parent, "name", None) or [])
                if index not in names:
                    raise RecordingError(f"{what}: {quote(walked)} has no entry named {quote(index)}; "
                                         f"the message's name field holds {listing(names)}")
                index = names.index(index)
            if index is not None:
                if not isinstance(x, (np.ndarray, list, tuple)):
                    raise RecordingError(f"{what}: {quote(walked)} is not an array, so has no element [{index}]")
                if index >= len(x):
                    raise RecordingError(f"{what}: {quote(walked)} has {len(x)} value(s); allowed indices 0..{len(x) - 1}")
                x, walked = x[index], f"{walked}[{index}]"
        if isinstance(x, (np.ndarray, list, tuple)):
            raise RecordingError(f"{what}: {quote(walked)} is an array of {len(x)} value(s); pick one with {walked}[i]")
        if isinstance(x, (bool, np.bool_)) or not isinstance(x, (int, float, np.integer, np.floating)):
            raise RecordingError(f"{what}: {quote(walked)} is not a number ({type(x).__name__})")
        return float(x)


def parse_field(source: str, what: str) -> FieldPick:
    m = _SOURCE.fullmatch(source.strip())
    if m is None:
        raise RecordingError(f"{what}: cannot parse it; allowed: {FORMS}")
    steps = []
    for part in m[2].split("."):
        f = _FIELD.fullmatch(part)
        if f is None:
            raise RecordingError(f"{what}: cannot parse the field {quote(part)}; allowed: {FORMS}")
        steps.append((f[1], None if f[2] is None else int(f[2]) if f[2].isdigit() else f[2]))
    return FieldPick(m[1], tuple(steps))


def _stamp(msg: Any, log_time: int, clock: str) -> int:
    """The message's time [ns] on the chosen clock."""
    header = getattr(msg, "header", None)
    if clock == "log" or header is None:
        return log_time
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


@dataclass(frozen=True)
class LogTable:
    """The topics of a robot log; messages are read and decoded only by `merged`."""

    file: str
    path: Path
    names: tuple[str, ...]  # topics
    kind: ClassVar[str] = "topic"
    strict: ClassVar[bool] = False  # logs carry many topics beside the joint's
    lines: ClassVar[None] = None

    def merged(self, sources: Mapping[str, str], timestep: float | None,
               allow_gaps: bool) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """(signals on one uniform grid, how they were merged); `sources['t']` is the clock."""
        clock = sources["t"]
        if clock not in CLOCKS:
            raise RecordingError(f"{self.file}: t={quote(clock)}: the time of a robot log is one of "
                                 f"{', '.join(CLOCKS)} (header stamps, or log time)")
        picks = {name: parse_field(src, f"{self.file}: source {quote(src)} (for {name})")
                 for name, src in sources.items() if name != "t"}
        for name, p in picks.items():
            if p.topic not in self.names:
                raise RecordingError(f"{self.file}: topic {quote(p.topic)} (for {name}) not found; "
                                     f"topics: {listing(self.names)}")
        stamps: dict[str, list[int]] = {name: [] for name in picks}
        values: dict[str, list[float]] = {name: [] for name in picks}
        AnyReader, typestore = _rosbags()
        try:
            with AnyReader([self.path], default_typestore=typestore) as reader:
                wanted = [c for c in reader.connections if c.topic in {p.topic for p in picks.values()}]
                for conn, log_time, raw in reader.messages(connections=wanted):
                    msg = reader.deserialize(raw, conn.msgtype)
                    for name, p in picks.items():
                        if p.topic == conn.topic:
                            stamps[name].append(_stamp(msg, log_time, clock))
                            values[name].append(p.value(msg, f"{self.file}: source {quote(sources[name])} (for {name})"))
        except RecordingError:
            raise
        except Exception as exc:  # corrupt logs surface as many error types of the reader
            raise RecordingError(f"{self.file}: not a readable robot log ({type(exc).__name__}: {exc})") from None
        origin = min(min(s) for s in stamps.values() if s) if any(stamps.values()) else 0
        streams = {}
        for name, p in picks.items():
            if len(stamps[name]) < 2:
                raise RecordingError(f"{self.file}: topic {quote(p.topic)} (for {name}) has {len(stamps[name])} message(s)")
            order = np.argsort(stamps[name], kind="stable")
            # Integer nanoseconds from the log's first stamp: epoch seconds in float64 would
            # round a 1 kHz clock's steps by 1e-7 s.
            t = (np.asarray(stamps[name], np.int64)[order] - origin) * 1e-9
            check_time(t, Context(f"{self.file}: topic {p.topic!r} (for {name}, {clock} time)"), allow_gaps)
            streams[name] = (t, np.asarray(values[name])[order])
        try:
            return merge_streams(streams, timestep)
        except ValueError as exc:
            raise RecordingError(f"{self.file}: {exc}") from None


def read_log_table(path: Path) -> LogTable:
    """The topics of a ROS 2 bag folder or an MCAP file; the log is only read."""
    AnyReader, typestore = _rosbags()
    try:
        with AnyReader([path], default_typestore=typestore) as reader:
            topics = tuple(dict.fromkeys(c.topic for c in reader.connections))
    except Exception as exc:  # not a bag, truncated, unknown storage: the reader's own error types
        raise RecordingError(f"{path}: not a readable robot log ({type(exc).__name__}: {exc})") from None
    return LogTable(str(path), path, topics)
