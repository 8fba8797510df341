"""One evidence figure per named effect: the residual shown against what the effect explains.

Each effect's plot puts the before-model's residual next to the after-model's against the
variable the physics depends on, so the pattern the effect removes is visible:
- gear stiffness, hysteresis, damping, backlash: transmission torque against deflection
  (tau-delta loops; the measured loop under each model's);
- motor friction terms and an input offset: residual against motor velocity; load friction: against link velocity;
- gravity: residual against sin(theta); torque ripple: against q mod 2 pi;
- input delay: cross-correlation of measured and predicted signal over the shift;
- link flexibility: residual spectrum.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.signal import welch

from ..diagnosis.locate import located_conditions
from ..identify.effects import EFFECTS
from .compare import Comparison
from .plots import MEASURED, axis_label, flat, save, style

MAX_POINTS = 20_000   # scatter points per model: enough to see a shape, few enough for a small PNG
BINS = 30
RIPPLE_BINS_PER_CYCLE = 8
MAX_SHIFT_S = 0.05    # [s] cross-correlation range, as locate's lag search
ZOOM_WIDTHS = 5.0     # backlash loops are also drawn within +- this many play widths of delta = 0


def evidence_signal(effect: str, where: dict, available, default: str) -> str:
    """The signal whose located conditions point at ``effect`` most strongly (else ``default``)."""
    wanted = EFFECTS[effect].evidence
    best, score = default, -1.0
    for sig, c in located_conditions(where):
        if sig in available and c["name"] in wanted and c["significant"] and c["score"] > score:
            best, score = sig, c["score"]
    return best


def plot_evidence(effect: str, cmp: Comparison, before: str, after: str, where: dict,
                  parameters: dict[str, float], path: Path, default_signal: str) -> Path:
    """The evidence figure of ``effect`` (models ``before`` and ``after`` in ``cmp``)."""
    plot = EFFECTS[effect].plot
    if plot == "loops":
        # The play is a few 0.1 mrad inside loops spanning mrad: show it magnified too.
        width = parameters.get(f"{effect}.width")  # a dead zone's width
        fig = _loops(cmp, (before, after), None if width is None else ZOOM_WIDTHS * width)
    elif plot == "time_shift":  # the residual's cross-correlation
        signal = evidence_signal(effect, where, cmp.signals, default_signal)
        fig = _cross_correlation(cmp, (before, after), signal, parameters.get(EFFECTS[effect].params[0].name))
    elif plot == "spectrum":
        signal = evidence_signal(effect, where, cmp.signals, default_signal)
        fig = _spectrum(cmp, (before, after), signal)
    else:
        x, xlabel = condition_axis(effect, cmp)
        signal = evidence_signal(effect, where, cmp.signals, default_signal)
        if plot == "motor_revolution":  # equal bins over the revolution, fine enough for k cycles
            k = int(parameters.get(f"{effect}.harmonic", 1))
            edges = np.linspace(0.0, 2 * np.pi, max(BINS, RIPPLE_BINS_PER_CYCLE * k) + 1)
        else:  # equal counts: velocities crowd near zero, where friction changes fastest
            edges = np.unique(np.quantile(x[:, cmp.cost], np.linspace(0, 1, BINS + 1)))
        fig = _versus(cmp, (before, after), signal, x, xlabel, edges)
    fig.suptitle(f"{effect}: {EFFECTS[effect].physics}", fontsize=11)
    return save(fig, path)


def condition_axis(effect: str, cmp: Comparison) -> tuple[np.ndarray, str]:
    """The condition an effect's residual is plotted against (its ``Effect.plot``)."""
    c = cmp.conditions
    plot = EFFECTS[effect].plot
    if plot == "sin_theta":
        return np.sin(c["theta"]), "sin(theta) (measured link angle)"
    if plot == "motor_revolution":
        return np.mod(c["q"], 2 * np.pi), f"q mod 2 pi [{cmp.unit('rad')}] (motor angle within one revolution)"
    if plot == "link_velocity":
        return c["thetad"], f"link velocity theta' [{cmp.unit('rad/s')}]"
    if plot == "motor_velocity":
        return c["qd"], f"motor velocity q' [{cmp.unit('rad/s')}]"
    if plot == "measured_torque" and "tau" in cmp.measured:  # a torque cell's error grows with tau
        return cmp.measured["tau"], f"measured torque tau [{cmp.unit('N m')}]"
    raise ValueError(f"no evidence plot is defined for effect {effect!r}")


def _subsample(n: int) -> slice:
    return slice(None, None, max(1, -(-n // MAX_POINTS)))


def _versus(cmp: Comparison, labels, signal: str, x: np.ndarray, xlabel: str, edges: np.ndarray) -> Figure:
    """Residual against one condition: a scatter per model and its median in the bins ``edges``."""
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.subplots()
    xs = x[:, cmp.cost].ravel()
    centers = 0.5 * (edges[1:] + edges[:-1])
    pick = _subsample(xs.size)
    factor = cmp.display(signal)[1]
    for i, label in enumerate(labels):
        r = factor * cmp.residual(label, signal)[:, cmp.cost].ravel()
        st = style(i, len(labels))
        ax.plot(xs[pick], r[pick], ".", ms=1.5, alpha=0.25, color=st["color"])
        which = np.clip(np.digitize(xs, edges[1:-1]), 0, len(centers) - 1)
        med = np.array([np.nanmedian(r[which == k]) if np.any(which == k) else np.nan
                        for k in range(len(centers))])
        ax.plot(centers, med, color=st["color"], lw=2.2, label=f"measured - {label} (binned median)")
    ax.axhline(0, color="0.3", lw=0.8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(axis_label(cmp, signal, "residual of "))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    return fig


def _loops(cmp: Comparison, labels, zoom: float | None = None) -> Figure:
    """tau against delta per model, the measured loop in black under each; with ``zoom`` [rad]
    a second row shows |delta| <= zoom."""
    rows = 1 if zoom is None else 2
    fig = Figure(figsize=(10, 4.5 * rows), layout="constrained")
    axes = np.atleast_2d(fig.subplots(rows, len(labels), sharey="row"))
    dscale, tscale = cmp.display("delta")[1], cmp.display("tau")[1]
    has_tau = "tau" in cmp.measured
    for row in range(rows):
        for i, (ax, label) in enumerate(zip(axes[row], labels)):
            curves = [(flat(cmp.predicted[label]["delta"]), flat(cmp.predicted[label]["tau"]))]
            if has_tau:
                curves.append((flat(cmp.measured["delta"]), flat(cmp.measured["tau"])))
                ax.plot(dscale * curves[1][0], tscale * curves[1][1], alpha=0.6, **{**MEASURED, "lw": 0.6})
            ax.plot(dscale * curves[0][0], tscale * curves[0][1], label=f"model {label}",
                    **{**style(i, len(labels)), "lw": 0.8})
            if row == 1:
                _zoom(ax, curves, zoom, dscale, tscale)
            ax.set_xlabel(axis_label(cmp, "delta"))
            ax.grid(True, alpha=0.3)
            ax.legend(loc="upper left", fontsize=8)
            ax.set_title(f"model {label}" + (" near delta = 0" if row else "")
                         + ("" if has_tau else " (no torque recorded: model loops only)"), fontsize=9)
        axes[row][0].set_ylabel(axis_label(cmp, "tau"))
    return fig


def _zoom(ax, curves, zoom: float, dscale: float, tscale: float) -> None:
    ax.set_xlim(-dscale * zoom, dscale * zoom)
    inside = np.concatenate([y[np.abs(x) <= zoom] for x, y in curves])
    inside = inside[np.isfinite(inside)]
    if inside.size:
        lo, hi = tscale * inside.min(), tscale * inside.max()
        pad = 0.05 * (hi - lo) + 1e-12
        ax.set_ylim(lo - pad, hi + pad)


def cross_correlation(measured: np.ndarray, predicted: np.ndarray, max_shift: int) -> tuple[np.ndarray, np.ndarray]:
    """(shifts d, correlation of measured(i) with predicted(i - d)) over windows x samples.

    Each window's mean is removed and both sides are taken over one fixed inner stretch of
    the measured window, so every shift compares the same measured samples; d > 0 means the
    measurement lags the prediction.
    """
    n = measured.shape[1]
    k = min(max_shift, n // 4)
    m = measured[:, k:n - k]
    m = m - m.mean(axis=1, keepdims=True)
    shifts = np.arange(-k, k + 1)
    out = np.empty(shifts.size)
    for j, d in enumerate(shifts):
        p = predicted[:, k - d:n - k - d]
        p = p - p.mean(axis=1, keepdims=True)
        denom = np.sqrt(np.sum(m ** 2) * np.sum(p ** 2))
        out[j] = np.sum(m * p) / denom if denom > 0 else np.nan
    return shifts, out


def peak_shift(shifts: np.ndarray, corr: np.ndarray) -> float:
    """Shift of the correlation maximum, refined between samples by a parabola through it."""
    k = int(np.nanargmax(corr))
    if 0 < k < len(corr) - 1:
        y0, y1, y2 = corr[k - 1:k + 2]
        curv = y0 - 2 * y1 + y2
        if curv < 0:
            return float(shifts[k] + 0.5 * (y0 - y2) / curv)
    return float(shifts[k])


def _cross_correlation(cmp: Comparison, labels, signal: str, delay: float | None) -> Figure:
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.subplots()
    dt = float(np.median(np.diff(cmp.t[0])))
    max_shift = int(round(MAX_SHIFT_S / dt))
    for i, label in enumerate(labels):
        pred = np.nan_to_num(cmp.predicted[label][signal])
        shifts, corr = cross_correlation(cmp.measured[signal], pred, max_shift)
        st = style(i, len(labels))
        peak = 1e3 * dt * peak_shift(shifts, corr)
        ax.plot(1e3 * dt * shifts, corr, color=st["color"], ls=st["ls"], label=f"model {label}: peak at {peak:+.1f} ms")
        ax.axvline(peak, color=st["color"], lw=0.8, alpha=0.6)
    if delay is not None:
        ax.axvline(1e3 * delay, color="black", ls=":", lw=1.2, label=f"fitted delay {1e3 * delay:.2f} ms")
    ax.set_xlabel("shift d [ms] (d > 0: measurement lags the prediction)")
    ax.set_ylabel(f"correlation of measured and predicted {signal}")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="lower center", fontsize=8)
    return fig


def _spectrum(cmp: Comparison, labels, signal: str) -> Figure:
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.subplots()
    dt = float(np.median(np.diff(cmp.t[0])))
    factor = cmp.display(signal)[1]
    for i, label in enumerate(labels):
        r = factor * np.nan_to_num(cmp.residual(label, signal)[:, cmp.cost])
        f, p = welch(r - r.mean(axis=1, keepdims=True), fs=1.0 / dt, nperseg=r.shape[1], axis=1)
        st = style(i, len(labels))
        ax.loglog(f[1:], p.mean(axis=0)[1:], color=st["color"], ls=st["ls"], label=f"measured - {label}")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"residual power of {signal} [{cmp.display(signal)[0]}^2/Hz]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    return fig
