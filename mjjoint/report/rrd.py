"""``traces.rrd``: measured signals and each model's windowed predictions on one ``sim_time`` line.

Entities ``/<label>/<signal>`` (label: measured, before, after, ...) in SI units, as the
simulate command logs them; ``/windows/heldout`` is 1 over held-out windows. The default
layout stacks one plot per signal with every label in it, so before/after read off directly.
Predictions restart from the measured state at every window start: the jumps there are real.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from matplotlib.colors import to_rgb

from ..viz.rerun_log import APP_ID, sim_time
from .compare import LABELS, Comparison
from .plots import MEASURED, style


def _colors(labels) -> dict[str, tuple[int, int, int]]:
    """The PNGs' colours: measured black, models as ``plots.style``."""
    rgb = lambda c: tuple(int(round(255 * x)) for x in to_rgb(c))  # noqa: E731
    return {"measured": rgb(MEASURED["color"]),
            **{label: rgb(style(i, len(labels))["color"]) for i, label in enumerate(labels)}}


def write_rrd(path: Path, cmp: Comparison, labels, recording_name: str) -> Path:
    """Write measured and every labelled prediction of ``cmp`` to ``path``."""
    roots = ["measured", *labels]
    colors = _colors(labels)
    views = [rrb.TimeSeriesView(name=LABELS[s], origin="/", contents=[f"/{r}/{s}" for r in roots])
             for s in cmp.signals]
    views.append(rrb.TimeSeriesView(name="held-out windows", origin="/", contents=["/windows/heldout"]))
    rec = rr.RecordingStream(APP_ID)
    rec.set_sinks(rr.FileSink(str(path)), default_blueprint=rrb.Blueprint(rrb.Vertical(*views)))
    rec.send_recording_name(recording_name)
    own = cmp.owned  # one value per time stamp
    time = [sim_time(cmp.t[own])]
    try:
        for root in roots:
            source = cmp.measured if root == "measured" else cmp.predicted[root]
            for s in cmp.signals:
                entity = f"{root}/{s}"
                rec.log(entity, rr.SeriesLines(names=f"{root} {s}", colors=[colors[root]]), static=True)
                rec.send_columns(entity, indexes=time,
                                 columns=rr.Scalars.columns(scalars=np.asarray(source[s], float)[own]))
        held = np.broadcast_to(cmp.heldout[:, None], cmp.t.shape)[own].astype(float)
        rec.log("windows/heldout", rr.SeriesLines(names="held out"), static=True)
        rec.send_columns("windows/heldout", indexes=time, columns=rr.Scalars.columns(scalars=held))
        rec.flush()
    finally:
        rec.disconnect()  # finishes the file (footer)
    return path
