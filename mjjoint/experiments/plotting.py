"""Shared matplotlib helpers for the experiment figures (Agg backend: files only, no display)."""
from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # after matplotlib.use: the backend must be chosen first

COLORS = ("tab:blue", "tab:red", "tab:green", "tab:orange", "tab:purple", "tab:brown")


def figure(nrows: int = 1, ncols: int = 1, width: float = 7.0, height: float = 4.0, **kw):
    """A figure with a grid on every axis; axes squeezed like ``plt.subplots``."""
    fig, axes = plt.subplots(nrows, ncols, figsize=(width, height), constrained_layout=True, **kw)
    for ax in np.atleast_1d(axes).ravel():
        ax.grid(True, which="both", alpha=0.3)
    return fig, axes


def save(fig, path: str | Path) -> Path:
    """Write the PNG (creating its folder) and release the figure."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
