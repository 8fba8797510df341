"""Write a designed experiment: the programme to run, and both rivals' predicted responses.

Into one folder (written whole or not at all by the caller, ``report.output.OutputDir``):
``experiment.csv`` (t,u: ``mjjoint simulate --excitation file --file experiment.csv`` runs it;
closed loop: t,theta_ref, the reference ``mjjoint simulate --controller ... --reference`` tracks),
``design.json`` (the experiment, D against the default chirp's, limits used, noise floor, the
rivals and every input evaluated), ``responses.png`` and ``responses.rrd`` (the rivals side by
side per signal, with where their difference exceeds the combined spread marked) and
``index.html`` tying them together.
"""
from __future__ import annotations

import dataclasses
from html import escape
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from matplotlib.figure import Figure

from ..report.output import MARKER, write_json
from ..viz.rerun_log import APP_ID, sim_time
from .criterion import separation
from .limits import usage
from .optimise import Design

UNITS = {"q": "rad", "theta": "rad", "tau": "N m"}
COLORS = ("tab:red", "tab:blue")


def summary(d: Design) -> dict:
    """design.json's data (no wall time: the same inputs give the same bytes)."""
    best, ref = d.best, d.reference
    exc = best.excitation
    return {"experiment": {"family": best.family, "point": list(best.point), "duration": d.limits.duration,
                           "rate": d.limits.rate, "excitation": {"kind": type(exc).__name__,
                                                                 **dataclasses.asdict(exc)},
                           "file": "experiment.csv", "loop": "open" if d.loop is None else "closed",
                           **({} if d.loop is None else {"controller": d.loop.describe()})},
            "discrimination_nats": best.score,   # for the rivals as fitted, every window
            "discrimination_heldout_nats": d.heldout_discrimination,
            "rehearsed_ratio_nats": d.rehearsed_ratio,
            "rehearsed": [{"family": c.family, "point": list(c.point), "discrimination_nats": c.score,
                           **c.rehearsal.as_dict()} for c in d.rehearsed],
            "default_chirp": {"discrimination_nats": ref.score, "limit_usage": ref.usage,
                              "excitation": dataclasses.asdict(ref.excitation),
                              "beaten": d.beats_reference, "why_not_beaten": d.unbeaten},
            "limit_usage": {r.effect: usage(tr, d.limits) for r, tr in zip(d.rivals, best.traces)},
            "limits": dataclasses.asdict(d.limits), "noise_floor": d.noise,
            "rivals": [r.describe() for r in d.rivals],
            "evaluated": [{"family": f, "point": list(p), "discrimination_nats": s, "limit_usage": u}
                          for f, p, s, u in d.evaluated]}


def separated(d: Design) -> dict[str, np.ndarray]:
    """Per signal and sample of the run: whether the rivals' windowed predictions there differ by
    more than noise and spread combined (in either rival's run)."""
    n = len(d.best.u)
    out = {s: np.zeros(n, bool) for s in d.limits.signals}
    for w in d.best.windowed:
        sep = separation(w, d.noise, d.limits.signals)
        step = int(w.samples[0, 1] - w.samples[0, 0])  # cost samples are decimated: fill between
        for s in d.limits.signals:
            at = w.samples[sep[s] > 1.0]
            for k in range(step):
                out[s][np.minimum(at + k, n - 1)] = True
    return out


def plot_responses(d: Design, path: Path) -> Path:
    """One panel per measured signal: both rivals' runs, shaded where they separate."""
    best = d.best
    sep = separated(d)
    fig = Figure(figsize=(10, 2.4 * (len(d.limits.signals) + 1)), layout="constrained")
    axes = fig.subplots(len(d.limits.signals) + 1, 1, sharex=True)
    t = best.traces[0].t
    if d.loop is None:
        axes[0].plot(t, best.u, color="0.3", lw=0.8)
    else:  # the reference, and each rival's command in the loop
        axes[0].plot(t, best.u, color="0.3", lw=0.8, label="theta_ref [rad]")
        for k, (rival, tr) in enumerate(zip(d.rivals, best.traces)):
            axes[0].plot(t, tr.u, color=COLORS[k], lw=0.8, label=f"u, {rival.effect}")
        axes[0].legend(loc="upper right", fontsize="small")
    axes[0].set(ylabel="u [N m]" if d.loop is None else "theta_ref, u",
                title=f"designed input: {best.family}, D = {best.score:.3g} nats "
                                        f"(default chirp {d.reference.score:.3g})")
    for ax, s in zip(axes[1:], d.limits.signals):
        for k, (rival, tr) in enumerate(zip(d.rivals, best.traces)):
            ax.plot(t, getattr(tr, s), color=COLORS[k], lw=1.0, label=rival.effect)
        lo, hi = ax.get_ylim()
        ax.fill_between(t, lo, hi, where=sep[s], color="gold", alpha=0.3, lw=0,
                        label="difference > noise + spread")
        ax.set_ylim(lo, hi)
        ax.set(ylabel=f"{s} [{UNITS[s]}]")
        ax.legend(loc="upper right", fontsize="small")
    axes[-1].set(xlabel="t [s]")
    fig.savefig(path, dpi=100)
    return path


def write_rrd(d: Design, path: Path) -> Path:
    """Both rivals' responses and the separation per signal on one ``sim_time`` line."""
    best = d.best
    sep = separated(d)
    views = [rrb.TimeSeriesView(name=s, origin="/",
                                contents=[f"/{r.effect}/{s}" for r in d.rivals] + [f"/separation/{s}"])
             for s in d.limits.signals]
    rec = rr.RecordingStream(APP_ID)
    rec.set_sinks(rr.FileSink(str(path)), default_blueprint=rrb.Blueprint(rrb.Vertical(*views)))
    rec.send_recording_name(f"design {' vs '.join(r.effect for r in d.rivals)}")
    time = [sim_time(best.traces[0].t)]
    try:
        series = {"input/u" if d.loop is None else "input/theta_ref": best.u}
        for r, tr in zip(d.rivals, best.traces):
            series.update({f"{r.effect}/{s}": getattr(tr, s) for s in d.limits.signals})
        series.update({f"separation/{s}": sep[s].astype(float) for s in d.limits.signals})
        for entity, values in series.items():
            rec.send_columns(entity, indexes=time, columns=rr.Scalars.columns(scalars=np.asarray(values, float)))
        rec.flush()
    finally:
        rec.disconnect()
    return path


def write_experiment(d: Design, path: Path) -> Path:
    """t,u at the design rate: the file ``mjjoint simulate --excitation file`` reads; closed
    loop: t,theta_ref, a reference file (``rehearse.ReferenceFile``)."""
    t = np.arange(len(d.best.u)) / d.limits.rate
    with path.open("w", encoding="utf-8", newline="") as f:  # repr: reads back to the same float
        f.write("t,u\n" if d.loop is None else "t,theta_ref\n")
        f.writelines(f"{a!r},{b!r}\n" for a, b in zip(t.tolist(), d.best.u.tolist()))
    return path


def page(data: dict, run: dict) -> str:
    rivals = " vs ".join(r["effect"] for r in data["rivals"])
    exp = data["experiment"]
    rows = "".join(f"<tr><td>{escape(k)}</td><td class=num>{v:.4g}</td></tr>"
                   for k, v in data["limit_usage"].items())
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>design: {escape(rivals)}</title>\n</head>\n<body>\n"
            f"<h1>Experiment separating {escape(rivals)}</h1>\n"
            f"<p>Input family <b>{escape(exp['family'])}</b>, {exp['duration']:g} s at {exp['rate']:g} Hz, "
            + ("open loop: <code>experiment.csv</code> (t,u; run it: <code>mjjoint simulate --excitation file "
               "--file experiment.csv</code>).</p>\n" if exp["loop"] == "open" else
               "closed loop: <code>experiment.csv</code> (t,theta_ref: the reference for the recording's "
               "controller, <code>mjjoint simulate --controller ... --limit MAX_TORQUE --reference "
               "experiment.csv</code>).</p>\n")
            + 
            f"<p>Expected log-likelihood ratio between the rivals as fitted: <b>{data['discrimination_nats']:.4g} "
            f"nats</b> (the default chirp of the same length: {data['default_chirp']['discrimination_nats']:.4g}), "
            f"{data['discrimination_heldout_nats']:.4g} over the held-out windows the decision compares"
            + ("" if data["rehearsed_ratio_nats"] is None else
               f"; the smaller rehearsed decision's: {data['rehearsed_ratio_nats']:.4g} nats (not a bound: the "
               "benchmark's realised ratios reached it in most draws, not all)")
            + ".</p>\n"
            f"<table><tr><th>rival</th><th>largest share of a limit used</th></tr>{rows}</table>\n"
            "<p><img src=\"responses.png\" alt=\"both rivals' predicted responses\" style=\"max-width:100%\"></p>\n"
            "<p>Shaded: where the rivals' predictions differ by more than the noise floor plus their "
            "parameter spread. <code>rerun responses.rrd</code> shows the same traces.</p>\n"
            f"<p class=muted>files: {escape(', '.join(run['files']))}</p>\n</body>\n</html>\n")


def write_design(folder: Path, d: Design, run: dict) -> dict:
    """Every file of a design in ``folder`` (run.json last); returns design.json's data."""
    data = summary(d)
    files = [write_json(folder / "design.json", data), write_experiment(d, folder / "experiment.csv"),
             plot_responses(d, folder / "responses.png"), write_rrd(d, folder / "responses.rrd")]
    run = {**run, "files": sorted([p.name for p in files] + ["index.html", MARKER])}
    (folder / "index.html").write_text(page(data, run), encoding="utf-8")
    write_json(folder / MARKER, run)
    return data
