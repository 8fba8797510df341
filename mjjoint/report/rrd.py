"""``traces.rrd``: measured signals and each model's windowed predictions on one ``sim_time`` line.

Entities ``/<label>/<signal>`` (label: measured, before, after, ...) in SI units, as the
simulate command logs them; ``/residual/<label>/<signal>`` is measured - predicted;
``/located/<signal>`` marks the windows where the diagnosis located the first model's mismatch
(a pulse as high as that model's largest residual, 0 elsewhere); ``/windows/heldout`` is 1 over
held-out windows. The default layout has one row per signal: measured and every model beside
their residuals with the located windows, so before/after read off directly.
Predictions restart from the measured state at every window start: the jumps there are real.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
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


def blueprint(signals: Sequence[str], labels: Sequence[str], located: bool) -> rrb.Blueprint:
    """One row per signal: measured and every model, beside the residuals (and located windows)."""
    rows = []
    for s in signals:
        marks = [f"/located/{s}"] if located else []
        rows.append(rrb.Horizontal(
            rrb.TimeSeriesView(name=LABELS[s], origin="/", contents=[f"/{r}/{s}" for r in ("measured", *labels)]),
            rrb.TimeSeriesView(name=f"residual of {s} (measured - model)", origin="/",
                               contents=[f"/residual/{r}/{s}" for r in labels] + marks)))
    rows.append(rrb.TimeSeriesView(name="held-out windows", origin="/", contents=["/windows/heldout"]))
    return rrb.Blueprint(rrb.Vertical(*rows))


def write_rrd(path: Path, cmp: Comparison, labels, recording_name: str,
              located: Mapping[str, Sequence[Sequence[float]]] | None = None) -> Path:
    """Write measured, every labelled prediction of ``cmp`` and its residual to ``path``;
    ``located``: signal -> [t0, t1, ...] windows where the first label's mismatch was located."""
    roots = ["measured", *labels]
    colors = _colors(labels)
    rec = rr.RecordingStream(APP_ID)
    rec.set_sinks(rr.FileSink(str(path)), default_blueprint=blueprint(cmp.signals, labels, located is not None))
    rec.send_recording_name(recording_name)
    own = cmp.owned  # one value per time stamp
    time = [sim_time(cmp.t[own])]

    def series(entity: str, name: str, values: np.ndarray, color=None) -> None:
        rec.log(entity, rr.SeriesLines(names=name, colors=None if color is None else [color]), static=True)
        rec.send_columns(entity, indexes=time, columns=rr.Scalars.columns(scalars=np.asarray(values, float)))

    try:
        for root in roots:
            source = cmp.measured if root == "measured" else cmp.predicted[root]
            for s in cmp.signals:
                series(f"{root}/{s}", f"{root} {s}", source[s][own], colors[root])
                if root != "measured":
                    series(f"residual/{root}/{s}", f"{root} residual", cmp.residual(root, s)[own], colors[root])
        for s in (cmp.signals if located is not None else ()):
            t, peak = cmp.t[own], np.nanmax(np.abs(cmp.residual(labels[0], s)[own]))
            inside = np.zeros(len(t), bool)
            for t0, t1, *_ in located.get(s, ()):
                inside |= (t >= t0) & (t <= t1)
            series(f"located/{s}", f"located ({labels[0]})", np.where(inside, peak, 0.0))
        held = np.broadcast_to(cmp.heldout[:, None], cmp.t.shape)[own].astype(float)
        series("windows/heldout", "held out", held)
        rec.flush()
    finally:
        rec.disconnect()  # finishes the file (footer)
    return path
