"""Reference trajectories of the position loop: the lab programme, or a CSV file.

References are angles [rad] of one side of the joint: ``side`` "link" (theta) or "motor"
(q = N theta at rest); ``on_side`` converts between them through the gear ratio.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..excitation import FromFile, sample_times
from ..params import check
from ..recordings.csv_io import read_csv_table

# reference column of a file -> the side it is an angle of
FILE_COLUMNS = {"q_ref": "motor", "theta_ref": "link"}


def on_side(values: np.ndarray, side: str, to: str, gear_ratio: float) -> np.ndarray:
    """A reference of ``side`` as one of side ``to`` (motor angle = N x link angle)."""
    if side == to:
        return values
    return values * gear_ratio if to == "motor" else values / gear_ratio


@dataclass(frozen=True)
class LabProgram:
    """The chapter's lab programme as a link-side reference; amplitudes in rad, durations scale
    with ``duration``."""

    duration: float = 20.0
    chirp_amplitude: float = 0.01    # +-0.6 deg around the hanging position
    sweep_amplitude: float = 1.2     # +-69 deg: gravity torque spans most of its range
    step_amplitude: float = 0.15
    seed: int = 0

    side = "link"

    def __post_init__(self) -> None:
        check("duration", self.duration, 2.0, 3600.0)

    def reference(self, t: np.ndarray) -> np.ndarray:
        """theta_ref(t): 40 % down-chirp, 30 % slow sweep, 30 % steps (random levels per seed)."""
        rng = np.random.default_rng(self.seed)
        T = self.duration
        ref = np.zeros_like(t)
        t1, t2 = 0.4 * T, 0.7 * T
        a = t < t1
        # Down-chirp 30 -> 1 Hz: instantaneous frequency f(t) = 30 * (1/30)^(t/t1).
        k = math.log(1 / 30) / t1
        phase = 2 * math.pi * 30 * (np.exp(k * t[a]) - 1) / k
        ref[a] = self.chirp_amplitude * np.sin(phase) * np.minimum(1.0, t[a] / 0.2)
        b = (t >= t1) & (t < t2)
        tb = t[b] - t1
        ref[b] = self.sweep_amplitude * 0.5 * (1 - np.cos(2 * math.pi * tb / (t2 - t1)))
        ref[b] *= 1 if rng.random() < 0.5 else -1
        c = t >= t2
        levels = rng.uniform(-1, 1, 6) * self.step_amplitude
        idx = np.minimum(((t[c] - t2) / ((T - t2) / 6)).astype(int), 5)
        ref[c] = levels[idx]
        return ref

    def sample(self, rate: float, duration: float) -> np.ndarray:
        return self.reference(sample_times(rate, duration))


class ReferenceFile:
    """A reference column of a CSV file: header t and q_ref (motor angle) or theta_ref (link
    angle) [rad], zero-order held as ``excitation.FromFile`` holds a torque."""

    def __init__(self, path: str | Path):
        header = read_csv_table(Path(path)).names
        found = [c for c in FILE_COLUMNS if c in header]
        if len(found) != 1:
            raise ValueError(f"{path}: a reference file needs exactly one of the columns "
                             f"{' or '.join(FILE_COLUMNS)} beside t (header: {','.join(header)})")
        self.source = FromFile(path, column=found[0])
        self.side = FILE_COLUMNS[self.source.column]

    @property
    def path(self) -> Path:
        return self.source.path

    @property
    def duration(self) -> float:
        return self.source.duration

    def sample(self, rate: float, duration: float) -> np.ndarray:
        return self.source.sample(rate, duration)
