"""Input families an experiment is searched in, each a map from [0, 1]^k to a torque programme.

Every family scales its programme so that its peak stays within ``peak`` by construction:
``Limits.max_torque`` for an open-loop torque, ``Limits.angle_range`` for a closed loop's
link-angle reference (``design.loop``). The coordinates are shares of the peak (amplitude,
offset) and log-spaced positions in the frequency or time range the record length and rate
allow, so one optimiser serves all.

* ``multisine``: amplitude, lowest line, band width (``excitation.Multisine``, 16 lines).
* ``chirp``: amplitude, start and end frequency of a linear sweep (``excitation.Chirp``, the
  shipped default's kind: the default chirp is a point of this family, ``chirp_point``, so
  that the search can start from it).
* ``dwell_reverse``: a constant offset plus a square wave that dwells at each level and
  reverses: held deflections of either sign, where play and hysteresis differ most.
* ``slow_reversal``: a constant offset plus a slow triangle: quasi-static reversals.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..excitation import Chirp, Multisine, sample_times
from ..params import check
from .limits import Limits

MIN_SHARE = 0.02     # smallest amplitude share of the peak a family uses
MULTISINE_LINES = 16
DWELL_RANGE = (0.05, 2.0)      # [s] time at each level of dwell_reverse
REVERSAL_RANGE = (0.05, 3.0)   # [Hz] triangle frequency of slow_reversal


WAVES = ("square", "triangle")


@dataclass(frozen=True)
class OffsetWave:
    """offset + amplitude w(t / period), w a unit square wave (each level held half a period,
    then reversed; +1 first) or a unit triangle (rising from 0, reversing twice per period)."""

    offset: float
    amplitude: float
    period: float
    wave: str = "square"

    def __post_init__(self) -> None:
        check("amplitude", self.amplitude, 0.0)
        check("period", self.period, 0.0, lo_open=True)
        check("offset", self.offset)
        if self.wave not in WAVES:
            raise ValueError(f"wave={self.wave!r} is not a wave (allowed: {', '.join(WAVES)})")

    def sample(self, rate: float, duration: float) -> np.ndarray:
        phase = (sample_times(rate, duration) / self.period) % 1.0
        if self.wave == "square":
            w = np.where(phase < 0.5, 1.0, -1.0)
        else:  # 0 at phase 0, +1 at 1/4, -1 at 3/4
            w = 1.0 - 4.0 * np.abs((phase + 0.25) % 1.0 - 0.5)
        return self.offset + self.amplitude * w


def _log_between(share: float, lo: float, hi: float) -> float:
    return float(math.exp(math.log(lo) + float(np.clip(share, 0, 1)) * (math.log(hi) - math.log(lo))))


def band(limits: Limits) -> tuple[float, float]:
    """The frequency range the search uses [Hz]: two periods in the record up to a tenth of the
    rate (and 40 Hz: the shipped joint's transmission modes lie below it)."""
    return max(2.0 / limits.duration, 0.1), min(0.1 * limits.rate, 40.0)


def _amplitude(share: float, room: float) -> float:
    return room * (MIN_SHARE + (1 - MIN_SHARE) * float(np.clip(share, 0, 1)))


def _log_amplitude(share: float, room: float) -> float:
    return room * _log_between(share, MIN_SHARE, 1.0)


def _offset(share: float, peak: float) -> float:
    return 0.9 * peak * (2 * float(np.clip(share, 0, 1)) - 1)


def multisine(p, limits: Limits, peak: float, amplitude=_amplitude) -> Multisine:
    lo, hi = band(limits)
    f_min = _log_between(p[1], lo, hi / 2)
    f_max = _log_between(p[2], f_min * 1.5, hi)
    lines = math.floor(f_max * limits.duration + 1e-9) - math.ceil(f_min * limits.duration - 1e-9) + 1
    return Multisine(amplitude=amplitude(p[0], peak), f_min=f_min, f_max=f_max,
                     n=max(1, min(MULTISINE_LINES, lines)))


def chirp(p, limits: Limits, peak: float, amplitude=_amplitude) -> Chirp:
    lo, hi = band(limits)
    return Chirp(amplitude=amplitude(p[0], peak), f_start=_log_between(p[1], lo, hi),
                 f_end=_log_between(p[2], lo, hi), sweep="linear")


def chirp_point(c: Chirp, limits: Limits, peak: float, log_amplitude: bool = False,
                nearest: bool = False) -> tuple[float, float, float] | None:
    """The ``chirp`` family's coordinates of the linear chirp ``c``, None where it lies outside
    the family (amplitude or frequencies out of range), or with ``nearest`` its nearest member's
    (a chirp of the same sweep below the family's smallest amplitude: the smallest)."""
    lo, hi = band(limits)
    share = c.amplitude / peak
    point = ((math.log(share / MIN_SHARE) / math.log(1 / MIN_SHARE) if log_amplitude and share > 0
              else (share - MIN_SHARE) / (1 - MIN_SHARE)),
             *(math.log(f / lo) / math.log(hi / lo) for f in (c.f_start, c.f_end)))
    if c.sweep != "linear" or not (nearest or all(-1e-12 <= v <= 1 + 1e-12 for v in point)):
        return None
    return tuple(float(np.clip(v, 0.0, 1.0)) for v in point)


def dwell_reverse(p, limits: Limits, peak: float, amplitude=_amplitude) -> OffsetWave:
    offset = _offset(p[1], peak)
    return OffsetWave(offset=offset, amplitude=amplitude(p[0], peak - abs(offset)),
                      period=2 * _log_between(p[2], *DWELL_RANGE), wave="square")


def slow_reversal(p, limits: Limits, peak: float, amplitude=_amplitude) -> OffsetWave:
    offset = _offset(p[1], peak)
    f_lo = max(REVERSAL_RANGE[0], 1.0 / limits.duration)
    return OffsetWave(offset=offset, amplitude=amplitude(p[0], peak - abs(offset)),
                      period=1.0 / _log_between(p[2], f_lo, max(REVERSAL_RANGE[1], f_lo)), wave="triangle")


# name -> (dimension, decoder from [0, 1]^k to an excitation with sample(rate, duration))
FAMILIES = {"multisine": (3, multisine), "chirp": (3, chirp), "dwell_reverse": (3, dwell_reverse),
            "slow_reversal": (3, slow_reversal)}


def programme(family: str, p, limits: Limits, peak: float | None = None, log_amplitude: bool = False):
    """The excitation of ``family`` at coordinates ``p``, and its samples, within ``peak``
    (default the torque limit); ``log_amplitude``: the amplitude share log-spaced from MIN_SHARE
    to 1 (a reference: its fast members meet the speed limit only at small amplitudes)."""
    if family not in FAMILIES:
        raise ValueError(f"family={family!r} is not an input family (allowed: {', '.join(FAMILIES)})")
    peak = limits.max_torque if peak is None else peak
    excitation = FAMILIES[family][1](np.asarray(p, float), limits, peak,
                                     _log_amplitude if log_amplitude else _amplitude)
    return excitation, excitation.sample(limits.rate, limits.duration)
