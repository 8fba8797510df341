"""PNG figures comparing measured windows with model predictions over time.

Matplotlib ``Figure`` objects without pyplot: no GUI backend, no global state between calls.
The first model label is drawn as "before" (red, dashed), the last as "after" (blue).
"""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .compare import LABELS, Comparison

MEASURED = dict(color="black", lw=1.2, label="measured")
STYLES = ({"color": "tab:red", "ls": "--", "lw": 1.2}, {"color": "tab:blue", "ls": "-", "lw": 1.0},
          {"color": "tab:green", "ls": "-.", "lw": 1.0})
DPI = 100


def style(i: int, n: int) -> dict:
    """Line style of model ``i`` of ``n``: the last is blue (the result), the first of several red."""
    return STYLES[1] if i == n - 1 else STYLES[0] if i == 0 else STYLES[2]


def flat(a: np.ndarray) -> np.ndarray:
    """windows x samples -> one line with a NaN gap after each window (predictions restart there)."""
    a = np.asarray(a, float)
    return np.concatenate([a, np.full((a.shape[0], 1), np.nan)], axis=1).ravel()


def axis_label(cmp: Comparison, signal: str, what: str = "") -> str:
    return f"{what}{LABELS[signal]} [{cmp.display(signal)[0]}]"


def save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    return path


def worst_windows(cmp: Comparison, signal: str, label: str, count: int) -> np.ndarray:
    """Held-out windows (all windows if none) where ``label`` predicts ``signal`` worst."""
    pool = np.flatnonzero(cmp.heldout) if cmp.heldout.any() else np.arange(len(cmp.t))
    err = np.nanmean(np.nan_to_num(cmp.residual(label, signal)[pool][:, cmp.cost], nan=np.inf) ** 2, axis=1)
    return np.sort(pool[np.argsort(-err, kind="stable")[:count]])


def plot_windows(cmp: Comparison, signal: str, labels: Sequence[str], path: Path, count: int = 4,
                 rank_by: str | None = None) -> Path:
    """Measured vs predicted ``signal`` on the held-out windows predicted worst by ``rank_by``."""
    wins = worst_windows(cmp, signal, rank_by or labels[0], count)
    height = 2.2 * len(wins) + 1.0
    fig = Figure(figsize=(10, height))
    # Fixed margins: constrained layout costs ~1 s on four panels and gains nothing here.
    fig.subplots_adjust(left=0.08, right=0.98, top=1 - 0.75 / height, bottom=0.5 / height, hspace=0.45)
    axes = np.atleast_1d(fig.subplots(len(wins), 1))
    factor = cmp.display(signal)[1]
    for ax, w in zip(axes, wins):
        t = cmp.t[w]
        meas = factor * cmp.measured[signal][w]
        ax.plot(t, meas, **MEASURED)
        for i, label in enumerate(labels):
            pred = factor * cmp.predicted[label][signal][w]
            ax.plot(t, pred, label=label, **style(i, len(labels)))
        # Keep the measured signal readable when a bad model runs far off: clip the view.
        lo, hi = np.nanmin(meas), np.nanmax(meas)
        pad = 0.5 * (hi - lo) + 1e-12
        ax.set_ylim(lo - pad, hi + pad)
        ax.axvspan(t[0], t[~cmp.cost][-1] if (~cmp.cost).any() else t[0], color="0.9", lw=0)
        ax.set_ylabel(cmp.display(signal)[0])
        ax.grid(True, alpha=0.3)
        ax.set_title(f"held-out window at {t[0]:.2f} s" if cmp.heldout[w] else f"window at {t[0]:.2f} s",
                     fontsize=9, loc="left")
    axes[0].legend(loc="upper right", fontsize=8, ncol=len(labels) + 1)
    axes[-1].set_xlabel("time [s] (grey: warm-up, not in the cost)")
    fig.suptitle(f"{LABELS[signal]}: measured vs predicted, {len(wins)} held-out windows")
    return save(fig, path)


def plot_residual_time(cmp: Comparison, signal: str, labels: Sequence[str], path: Path,
                       located: Sequence[Sequence[float]] = ()) -> Path:
    """Prediction residual of ``signal`` over the whole recording, located windows shaded."""
    fig = Figure(figsize=(10, 3.6), layout="constrained")
    ax = fig.subplots()
    factor = cmp.display(signal)[1]
    t = flat(cmp.t)
    for i, label in enumerate(labels):
        ax.plot(t, factor * flat(cmp.residual(label, signal)), label=f"measured - {label}",
                **{**style(i, len(labels)), "ls": "-"}, alpha=0.8)
    for k, win in enumerate(located):
        t0, t1, share = win[:3]
        ax.axvspan(t0, t1, color="orange", alpha=0.25, lw=0,
                   label="located" if k == 0 else None)
        ax.text(t0, 0.97, f" {100 * share:.0f} %", transform=ax.get_xaxis_transform(), va="top",
                fontsize=8, color="darkorange")
    for w in np.flatnonzero(cmp.heldout):  # a bar along the bottom marks held-out windows
        ax.axvspan(cmp.t[w, 0], cmp.t[w, -1], ymin=0, ymax=0.03, color="0.4", lw=0,
                   label="held out" if w == np.flatnonzero(cmp.heldout)[0] else None)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(axis_label(cmp, signal, "residual of "))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("where the prediction misses (shaded: located windows, % of residual energy)")
    return save(fig, path)
