"""A PNG overview of one trace: angles, deflection, transmission torque, motor-side torques."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..sim import Trace


def plot_trace(trace: Trace, path: str | Path, title: str | None = None) -> Path:
    """Write the overview figure of ``trace`` to ``path`` (format from its suffix)."""
    fig = Figure(figsize=(9, 10), layout="constrained")
    ax = fig.subplots(4, 1, sharex=True)
    ax[0].plot(trace.t, np.degrees(trace.q / trace.gear_ratio), label="q / N")
    ax[0].plot(trace.t, np.degrees(trace.theta), "--", label="theta")
    ax[0].set_ylabel("angle [deg]")
    ax[1].plot(trace.t, 1e3 * trace.delta)
    ax[1].set_ylabel("deflection delta [mrad]")
    ax[2].plot(trace.t, trace.tau, label="transmission tau")
    ax[2].plot(trace.t, trace.load_friction, label="load friction")
    ax[2].set_ylabel("link side [N m]")
    ax[3].plot(trace.t, trace.u, label="input u")
    ax[3].plot(trace.t, trace.friction, label="motor friction")
    ax[3].set_ylabel("motor side [N m]")
    ax[3].set_xlabel("time [s]")
    for a in ax:
        a.grid(True, alpha=0.3)
        if a.get_legend_handles_labels()[0]:
            a.legend(loc="upper right")
    if title:
        fig.suptitle(title)
    path = Path(path)
    fig.savefig(path, dpi=100)
    return path
