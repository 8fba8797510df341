"""Robot logs (ROS 2 bags, MCAP files) as recordings: small logs written with rosbags' own writer."""

from __future__ import annotations

import builtins
import shutil
from pathlib import Path

import numpy as np
import pytest

from mjjoint.recordings import RecordingError, parse_column_map, read_recording
from mjjoint.recordings.resample import describe

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

TS = get_typestore(Stores.ROS2_HUMBLE)
START = 1_700_000_000 * 10**9  # header stamps in epoch nanoseconds, as a robot's clock gives them
JOINT_RATE, CMD_RATE, DURATION = 1000, 250, 0.2
COLUMNS = "q=/joint_states.position[1],theta=/joint_states.position[0],tau=/joint_states.effort[1],u=/cmd.data"


def u_of(t):
    return 0.5 + 2.0 * t  # linear: interpolation between the 250 Hz samples is exact


def write_log(path: Path, storage: StoragePlugin, latency_ns: int = 0, swap: bool = False) -> None:
    """/joint_states (JointState, header stamps on a 1 kHz clock, logged `latency_ns` later) and
    /cmd (Float64, no header: log time only) at 250 Hz, starting 3 ms after the joints. `swap`:
    every other JointState lists its joints in the other order, as publishers may."""
    joint_state, header, stamp = (TS.types[k] for k in ("sensor_msgs/msg/JointState", "std_msgs/msg/Header",
                                                         "builtin_interfaces/msg/Time"))
    f64 = TS.types["std_msgs/msg/Float64"]
    with Writer(path, version=9, storage_plugin=storage) as w:
        joints = w.add_connection("/joint_states", joint_state.__msgtype__, typestore=TS)
        cmd = w.add_connection("/cmd", f64.__msgtype__, typestore=TS)
        w.add_connection("/diagnostics_text", "std_msgs/msg/String", typestore=TS)
        for k in range(int(DURATION * JOINT_RATE) + 1):
            ns = START + k * 10**9 // JOINT_RATE
            t = k / JOINT_RATE
            order = [1, 0] if swap and k % 2 else [0, 1]
            msg = joint_state(header=header(stamp=stamp(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="arm"),
                              name=[["link", "motor"][i] for i in order],
                              position=np.array([np.sin(t), 100 * np.sin(t)])[order],
                              velocity=np.zeros(2), effort=np.array([0.0, 3 * np.cos(t)])[order])
            w.write(joints, ns + latency_ns, TS.serialize_cdr(msg, joint_state.__msgtype__))
        for k in range(int(DURATION * CMD_RATE) + 1):
            t = 0.003 + k / CMD_RATE
            w.write(cmd, START + round(t * 1e9), TS.serialize_cdr(f64(data=u_of(t)), f64.__msgtype__))


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("logs")
    out = {}
    for storage in (StoragePlugin.SQLITE3, StoragePlugin.MCAP):
        out[storage.name] = root / f"bag_{storage.name.lower()}"
        write_log(out[storage.name], storage)
    out["file"] = root / "run.mcap"  # a bare MCAP file, as loggers other than ros2 bag write them
    shutil.copy(next(out["MCAP"].glob("*.mcap")), out["file"])
    return out


@pytest.mark.parametrize("kind", ["SQLITE3", "MCAP", "file"])
def test_topics_at_two_rates_merge_onto_one_grid(logs: dict[str, Path], kind: str) -> None:
    rec = read_recording(logs[kind], columns=parse_column_map(COLUMNS), gear_ratio=100.0)
    # The joints' 1 kHz clock sets the grid; it spans the time both topics cover.
    assert rec.dt == pytest.approx(1e-3, rel=1e-9)
    assert rec.t[0] == pytest.approx(0.003, abs=1e-12) and rec.t[-1] <= DURATION + 1e-12
    np.testing.assert_allclose(np.diff(rec.t), 1e-3, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec.u, u_of(rec.t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec.q, 100 * np.sin(rec.t), rtol=0, atol=1e-9)
    np.testing.assert_allclose(rec.theta, np.sin(rec.t), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec.tau, 3 * np.cos(rec.t), rtol=0, atol=1e-9)
    report = rec.meta["resampled"]
    assert report["method"] == "linear interpolation" and report["rate"] == pytest.approx(1000)
    assert report["stream_rates"]["u"] == pytest.approx(CMD_RATE) and report["stream_rates"]["q"] == pytest.approx(1000)
    assert "merged by linear interpolation onto 1000 Hz" in describe(report)
    assert rec.meta["format"] == ("mcap" if kind == "file" else "rosbag2")


def test_header_stamps_or_log_time(tmp_path: Path) -> None:
    """Header stamps place a message when it was measured; log time when it arrived (here 7 ms
    later), so t=log shifts the joint signals by the latency against the command."""
    path = tmp_path / "late"
    write_log(path, StoragePlugin.MCAP, latency_ns=7_000_000)
    by_stamp = read_recording(path, columns=parse_column_map(COLUMNS))
    by_log = read_recording(path, columns=parse_column_map(COLUMNS + ",t=log"))
    # The command's value tells the true time of each grid point, whatever t's origin.
    def true_time(rec):
        return (rec.u - u_of(0.0)) / (u_of(1.0) - u_of(0.0))
    np.testing.assert_allclose(by_stamp.theta, np.sin(true_time(by_stamp)), atol=1e-12)
    np.testing.assert_allclose(by_log.theta, np.sin(true_time(by_log) - 0.007), atol=1e-12)


def test_joint_state_entries_by_name(logs: dict[str, Path], tmp_path: Path) -> None:
    """By name, a joint's entry is found in every message, whatever order the message lists them in."""
    by_index = read_recording(logs["MCAP"], columns=parse_column_map(COLUMNS))
    swapped = tmp_path / "swapped"
    write_log(swapped, StoragePlugin.MCAP, swap=True)
    named = COLUMNS.replace("position[1]", "position[motor]").replace("position[0]", "position[link]")
    by_name = read_recording(swapped, columns=parse_column_map(named.replace("effort[1]", "effort[motor]")))
    for name, x in by_index.signals().items():
        np.testing.assert_array_equal(getattr(by_name, name), x, err_msg=name)


@pytest.mark.parametrize(
    ("columns", "expected"),
    [
        ("q=/joint_state.position[1]", ["topic '/joint_state' (for q) not found", "'/joint_states'", "'/cmd'"]),
        ("q=/joint_states.pos[1]", ["has no field 'pos'", "'position'"]),
        ("q=/joint_states.position", ["is an array of 2 value(s)", "position[i]"]),
        ("q=/joint_states.position[2]", ["has 2 value(s); allowed indices 0..1"]),
        ("q=/joint_states.position[wrist]", ["has no entry named 'wrist'", "'link', 'motor'"]),
        ("q=/joint_states.header.frame_id", ["'/joint_states.header.frame_id' is not a number (str)"]),
        ("q=joint_states.position[1]", ["cannot parse it", "/TOPIC.FIELD"]),
        ("t=wall", ["t='wall'", "header, log"]),
        ("q=/diagnostics_text.data", ["topic '/diagnostics_text' (for q) has 0 message(s)"]),
    ],
)
def test_log_mapping_errors_name_topic_and_field(logs: dict[str, Path], columns: str, expected: list[str]) -> None:
    mapping = {**parse_column_map(COLUMNS), **parse_column_map(columns)}
    with pytest.raises(RecordingError) as err:
        read_recording(logs["MCAP"], columns=mapping)
    message = str(err.value)
    assert "\n" not in message and str(logs["MCAP"]) in message
    for part in expected:
        assert part in message


def test_unmapped_log_names_the_topics(logs: dict[str, Path]) -> None:
    with pytest.raises(RecordingError, match=r"missing required topic\(s\) u, q, theta; topics present: '/joint_states'"):
        read_recording(logs["SQLITE3"])


def test_corrupt_log_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "broken.mcap"
    path.write_bytes(b"\x89MCAP0\r\n" + bytes(100))
    with pytest.raises(RecordingError, match="not a readable robot log"):
        read_recording(path)


def test_missing_extra_is_named(logs: dict[str, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    real_import = builtins.__import__

    def no_rosbags(name, *args, **kwargs):
        if name.startswith("rosbags"):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_rosbags)
    with pytest.raises(RecordingError, match=r"needs the optional extra 'robotlogs': pip install 'mjjoint\[robotlogs\]'"):
        read_recording(logs["file"], columns=parse_column_map(COLUMNS))
