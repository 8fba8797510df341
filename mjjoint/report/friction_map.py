"""The output folder of ``mjjoint diagnose --friction-map``: friction_map.json, the map's plot, run.json."""
from __future__ import annotations

from pathlib import Path

from matplotlib.figure import Figure

from ..identify.friction_map import FrictionLog, FrictionMap
from .output import MARKER, write_json
from .plots import save


def plot_friction_map(log: FrictionLog, result: FrictionMap, path: Path) -> Path:
    """Measured friction torque against the measured velocity, with the base and final fits."""
    fig = Figure(figsize=(8, 5))
    ax = fig.add_subplot()
    w = log.w
    ax.plot(w, log.tau, ".", ms=1.5, color="0.6", label="measured")
    for fit, color in ((result.base, "tab:blue"), (result.final, "tab:red")):
        label = f"{' + '.join(fit.effects)} (RMS {fit.rms:.3g} N m)"
        ax.plot(w, fit.prediction, ".", ms=1.0, color=color, label=label)
    ax.set_xlabel("velocity [rad/s]")
    ax.set_ylabel("friction torque [N m]")
    ax.axhline(0.0, color="0.85", lw=0.8)
    ax.legend(loc="upper left", fontsize=8, markerscale=6)
    ax.set_title("friction map: measured and fitted")
    return save(fig, path)


def write_friction_map(folder: Path, log: FrictionLog, result: FrictionMap, run: dict) -> dict:
    """Every file of a friction-map diagnosis in ``folder``; returns the friction_map.json data."""
    data = result.as_dict()
    files = [write_json(folder / "friction_map.json", data), plot_friction_map(log, result, folder / "friction_map.png")]
    write_json(folder / MARKER, {**run, "files": sorted([p.name for p in files] + [MARKER])})
    return data


def summary(data: dict) -> str:
    """The terminal lines: effects named, parameters, friction RMS before and after [N m]."""
    base, final = data["base"], data["final"]
    lines = [f"friction RMS: {base['rms']:.4g} N m ({' + '.join(base['effects'])}) -> {final['rms']:.4g} N m "
             f"(held-out {base['rms_heldout']:.4g} -> {final['rms_heldout']:.4g} N m)"]
    lines.append("missing: " + (", ".join(data["missing"]) or "nothing beyond Coulomb and viscous friction"))
    lines += [f"  {name} = {value:.6g}" for name, value in final["parameters"].items()]
    return "\n".join(lines)
