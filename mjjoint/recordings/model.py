"""In-memory recordings: one joint (`Recording`) or several sharing a clock (`MultiRecording`).

Units are SI: t [s]; u motor torque [N·m, motor side]; q motor angle before the gear [rad];
theta link angle [rad]; tau transmission torque [N·m, link side].
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .columns import SIGNALS


def _split_index(t: np.ndarray, fraction: float) -> int:
    """First index of the held-out part when cutting at `fraction` of the duration."""
    if not 0 < fraction < 1:
        raise ValueError(f"split fraction must lie in (0, 1), got {fraction!r}")
    k = int(np.searchsorted(t, t[0] + fraction * (t[-1] - t[0]), side="left"))
    if not 0 < k < len(t):
        raise ValueError(f"split at fraction {fraction!r} leaves one part empty ({len(t)} samples)")
    return k


def _slice_index(t: np.ndarray, t0: float, t1: float) -> tuple[int, int]:
    """Index range of the samples with t0 <= t <= t1."""
    i0, i1 = int(np.searchsorted(t, t0, side="left")), int(np.searchsorted(t, t1, side="right"))
    if i1 <= i0:
        raise ValueError(f"no samples in [{t0!r}, {t1!r}] s (recording spans [{t[0]!r}, {t[-1]!r}] s)")
    return i0, i1


# eq=False: field-wise == on arrays is ambiguous; compare signals() explicitly.
@dataclass(frozen=True, eq=False)
class Recording:
    """One joint's signals on a common time base; arrays are float64, 1-D and read-only."""

    t: np.ndarray
    u: np.ndarray
    q: np.ndarray
    theta: np.ndarray
    tau: np.ndarray | None = None
    gear_ratio: float | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = None
        for name in SIGNALS:
            value = getattr(self, name)
            if value is None and name == "tau":
                continue
            # Own read-only copy, so the frozen recording cannot change under the caller's feet.
            arr = np.array(value, dtype=np.float64)
            if arr.ndim != 1:
                raise ValueError(f"{name} must be 1-D, got shape {arr.shape}")
            n = len(arr) if n is None else n
            if len(arr) != n:
                raise ValueError(f"{name} has {len(arr)} samples, t has {n}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if n == 0:
            raise ValueError("a recording needs at least one sample")
        if self.gear_ratio is not None:
            ratio = float(self.gear_ratio)
            if not (math.isfinite(ratio) and ratio > 0):
                raise ValueError(f"gear_ratio must be finite and positive, got {self.gear_ratio!r}")
            object.__setattr__(self, "gear_ratio", ratio)
        object.__setattr__(self, "meta", dict(self.meta))

    @property
    def n(self) -> int:
        """Number of samples."""
        return len(self.t)

    @property
    def dt(self) -> float:
        """Median sample period [s]; robust to jitter and to the odd long step."""
        if self.n < 2:
            raise ValueError("dt needs at least two samples")
        return float(np.median(np.diff(self.t)))

    @property
    def duration(self) -> float:
        """t[-1] - t[0] [s]."""
        return float(self.t[-1] - self.t[0])

    def signals(self) -> dict[str, np.ndarray]:
        """Present signals by name, t first, tau only if recorded."""
        return {name: getattr(self, name) for name in SIGNALS if getattr(self, name) is not None}

    def with_columns(self, **arrays: np.ndarray | None) -> Recording:
        """Copy with some of t, u, q, theta, tau replaced (tau=None drops it)."""
        unknown = sorted(set(arrays) - set(SIGNALS))
        if unknown:
            raise ValueError(f"unknown column(s) {unknown}; allowed: {', '.join(SIGNALS)}")
        return dataclasses.replace(self, **arrays)

    def split(self, fraction: float) -> tuple[Recording, Recording]:
        """(train, held_out): the first `fraction` of the duration and the rest, contiguous."""
        k = _split_index(self.t, fraction)
        return self._rows(0, k), self._rows(k, self.n)

    def slice(self, t0: float, t1: float) -> Recording:
        """The samples with t0 <= t <= t1."""
        return self._rows(*_slice_index(self.t, t0, t1))

    def _rows(self, start: int, stop: int) -> Recording:
        return dataclasses.replace(self, **{k: v[start:stop] for k, v in self.signals().items()})


@dataclass(frozen=True, eq=False)
class MultiRecording:
    """Several joints recorded together; joint j's columns are u{j}, q{j}, theta{j}, tau{j}."""

    joints: tuple[Recording, ...]
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        joints = tuple(self.joints)
        if not joints or not all(isinstance(j, Recording) for j in joints):
            raise ValueError("a MultiRecording needs one or more Recording objects")
        if not all(np.array_equal(j.t, joints[0].t) for j in joints[1:]):
            raise ValueError("all joints of a MultiRecording must share the same t")
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "meta", dict(self.meta))

    @property
    def t(self) -> np.ndarray:
        return self.joints[0].t

    @property
    def n(self) -> int:
        return self.joints[0].n

    @property
    def dt(self) -> float:
        return self.joints[0].dt

    @property
    def duration(self) -> float:
        return self.joints[0].duration

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    def joint(self, i: int) -> Recording:
        """Joint i, numbered from 1 like the column suffixes (u1, q1, ...)."""
        if not 1 <= i <= len(self.joints):
            raise IndexError(f"joint {i} does not exist; joints are numbered 1..{len(self.joints)}")
        return self.joints[i - 1]

    def signals(self) -> dict[str, np.ndarray]:
        """t, then each joint's signals with its number appended (u1, q1, theta1, tau1, u2, ...)."""
        out = {"t": self.t}
        for j, rec in enumerate(self.joints, start=1):
            out.update({f"{k}{j}": v for k, v in rec.signals().items() if k != "t"})
        return out

    def split(self, fraction: float) -> tuple[MultiRecording, MultiRecording]:
        """(train, held_out) cut at `fraction` of the duration, as Recording.split."""
        k = _split_index(self.t, fraction)
        return self._rows(0, k), self._rows(k, self.n)

    def slice(self, t0: float, t1: float) -> MultiRecording:
        """The samples with t0 <= t <= t1."""
        return self._rows(*_slice_index(self.t, t0, t1))

    def _rows(self, start: int, stop: int) -> MultiRecording:
        return dataclasses.replace(self, joints=tuple(j._rows(start, stop) for j in self.joints))
