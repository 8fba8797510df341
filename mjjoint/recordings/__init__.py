"""Recordings I/O: read, check and write single- and multi-joint recordings (SI units)."""

from .columns import DEG, parse_column_map, parse_scales
from .csv_io import write_recording
from .errors import RecordingError
from .model import MultiRecording, Recording
from .read import read_recording, read_signals, reading_notes

__all__ = [
    "DEG",
    "MultiRecording",
    "Recording",
    "RecordingError",
    "parse_column_map",
    "parse_scales",
    "read_recording",
    "read_signals",
    "reading_notes",
    "write_recording",
]
