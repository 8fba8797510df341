"""Jittered or non-uniform timestamps onto a uniform grid, by linear interpolation.

The simulator and the identification step the model at a fixed period, so every signal is
brought onto t0 + k*dt. The nominal period dt is the recording's mean period (intervals
counted in median sample intervals, so a dropped sample counts twice) rounded to the
roundest rate or period the timestamps' jitter allows (1000.02 Hz -> 1 kHz, 333.33 Hz ->
3 ms), or to a whole multiple of a given timestep.
A recording whose intervals all lie within STEP_TOLERANCE of dt is left as recorded.
Linear interpolation is the one method: quantised signals (encoder angles) come back as
values between their levels, never smoothed beyond the two neighbouring samples.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

STEP_TOLERANCE = 1e-6  # relative; the model rate check (1/timestep divided by an integer) allows the same


def nominal_period(mean_step: float, timestep: float | None = None, tolerance: float = STEP_TOLERANCE) -> float:
    """The round sample period [s] within `tolerance` (relative) of the measured mean step.

    With a timestep: the nearest whole multiple of it. Otherwise the rate or the period
    with the fewest significant digits (1 to 6) that is close enough, else mean_step itself.
    """
    if timestep is not None:
        return max(1, round(mean_step / timestep)) * timestep
    for digits in range(1, 7):
        by_rate = 1.0 / float(f"{1.0 / mean_step:.{digits}g}")
        by_period = float(f"{mean_step:.{digits}g}")
        best = min(by_rate, by_period, key=lambda p: abs(p / mean_step - 1))
        if abs(best / mean_step - 1) <= tolerance:
            return best
    return mean_step


def clock_estimate(t: np.ndarray) -> tuple[float, float]:
    """(mean period, jitter) [s] from timestamps with jitter and dropped samples.

    An interval spans one period, or round(step / median step) periods from 1.75 median
    steps on (dropped samples; jitter alone rarely stretches a step that far); the mean period is the duration over the periods spanned. The uncertainty is
    twice the largest timestamp residual from that clock, over the duration.
    """
    steps = np.diff(t)
    ratio = steps / np.median(steps)
    periods = np.where(ratio < 1.75, 1.0, np.round(ratio))
    k = np.concatenate([[0.0], np.cumsum(periods)])
    dt, start = np.polyfit(k, t - t[0], 1)
    return float(dt), float(np.max(np.abs(t - t[0] - start - k * dt)))


def to_uniform_grid(
    signals: Mapping[str, np.ndarray], timestep: float | None = None
) -> tuple[dict[str, np.ndarray], dict[str, Any] | None]:
    """(signals on a uniform grid, what was done) or (signals, None) when already uniform.

    `signals` must hold 't', strictly increasing (validate.check_signals). The report holds
    the method, the new rate and period, the sample counts, the largest deviation of a
    recorded interval from the period and of a timestamp from the recording's own uniform
    clock (clock_estimate) [s], and the longest recorded step [s].
    """
    t = signals["t"]
    steps = np.diff(t)
    mean_step, jitter = clock_estimate(t)
    # The mean period is known to about the jitter at both ends over the duration.
    dt = nominal_period(mean_step, timestep, max(4 * jitter / (t[-1] - t[0]), STEP_TOLERANCE))
    step_dev = float(np.max(np.abs(steps - dt)))
    # Timestamps far from zero (Unix time: 1.7e9 s) are stored to their float spacing, 2.4e-7 s
    # there: steps that deviate by no more than that are a uniform clock, as recorded.
    if step_dev <= max(STEP_TOLERANCE * dt, 4.0 * float(np.spacing(np.max(np.abs(t))))):
        return dict(signals), None
    n = int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1
    grid = t[0] + np.arange(n) * dt
    out = {name: grid if name == "t" else np.interp(grid, t, x) for name, x in signals.items()}
    report = {
        "method": "linear interpolation",
        "rate": 1.0 / dt,
        "period": dt,
        "samples_in": len(t),
        "samples_out": n,
        "max_step_deviation": step_dev,
        "max_timestamp_deviation": jitter,
        "largest_step": float(np.max(steps)),
    }
    return out, report


def merge_streams(
    streams: Mapping[str, tuple[np.ndarray, np.ndarray]], timestep: float | None = None
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Signals each with its own timestamps (name -> (t, x), t increasing) onto one uniform grid.

    The grid's period is the fastest stream's nominal period (as `to_uniform_grid`), its span
    the time all streams cover; every signal is interpolated linearly onto it, so a slower
    stream comes back as straight lines between its samples (held for none of them). The
    report names the method, the rate and each stream's own rate.
    """
    rates = {name: 1.0 / clock_estimate(t)[0] for name, (t, _) in streams.items()}
    t = streams[max(rates, key=rates.get)][0]
    mean_step, jitter = clock_estimate(t)
    dt = nominal_period(mean_step, timestep, max(4 * jitter / (t[-1] - t[0]), STEP_TOLERANCE))
    start, end = max(t[0] for t, _ in streams.values()), min(t[-1] for t, _ in streams.values())
    if end - start < dt:
        spans = ", ".join(f"{name} [{t[0]:.6g}, {t[-1]:.6g}] s" for name, (t, _) in streams.items())
        raise ValueError(f"the signals do not overlap in time ({spans})")
    n = int(np.floor((end - start) / dt + 1e-9)) + 1
    grid = start + np.arange(n) * dt
    out = {"t": grid, **{name: np.interp(grid, t, x) for name, (t, x) in streams.items()}}
    report = {"method": "linear interpolation", "rate": 1.0 / dt, "period": dt, "samples_out": n,
              "span": [float(start), float(grid[-1])], "stream_rates": rates}
    return out, report


def describe(report: Mapping[str, Any]) -> str:
    """One line for the user and the run record: how a recording was resampled or merged."""
    if "stream_rates" in report:
        rates = ", ".join(f"{name} {rate:.4g} Hz" for name, rate in report["stream_rates"].items())
        return (f"signals logged at their own rates ({rates}) merged by {report['method']} onto "
                f"{report['rate']:.6g} Hz ({report['samples_out']} samples over the {report['span'][1] - report['span'][0]:.6g} s they all cover)")
    return (
        f"timestamps not uniform: resampled by {report['method']} onto {report['rate']:.6g} Hz "
        f"({report['samples_in']} -> {report['samples_out']} samples; timestamps deviate up to "
        f"{report['max_timestamp_deviation']:.3g} s from a uniform clock, longest step {report['largest_step']:.3g} s)"
    )
