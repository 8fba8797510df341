"""Write the whole output folder of ``mjjoint diagnose`` or ``mjjoint fit``.

``diagnosis.json`` / ``fit.json`` hold results only: the same inputs and seed give the same
bytes. Wall times, the command line and the file list go to ``run.json``, written last
(see ``output``).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

from ..assets import ArmSpec
from ..assets.plant import input_range
from ..diagnosis.floor import Floor
from ..diagnosis.loop import Diagnosis
from ..identify.fit import FitResult
from ..identify.structure import Structure
from ..identify.windows import Predictor
from ..modelfile import dump_model_file
from .compare import compare, worst_signal
from .evidence import plot_evidence
from .html import diagnosis_page, fit_page
from .output import MARKER, write_json
from .plots import plot_residual_time, plot_windows
from .rrd import write_rrd
from .summary import step_values


def model_labels(n_steps: int) -> list[str]:
    """Labels of the fitted models in order: base ("before"), after each step, final ("after")."""
    if n_steps == 0:
        return ["fitted"]
    return ["before", *(f"after_step{k}" for k in range(1, n_steps)), "after"]


MODEL_FILE = "model.toml"


def write_model(folder: Path, structure: Structure, measured) -> list[Path]:
    """The fitted model as a model file that ``mjjoint simulate --model`` (and ``--model`` of fit
    and diagnose) takes back, at the recording's sample rate, its amplifier limit wide enough for
    the recorded input (``measured``); none for a direct drive, which model files do not
    describe."""
    plant, joint = structure.model_params()
    if not isinstance(plant, ArmSpec):
        return []
    plant = dataclasses.replace(plant, max_current=input_range(measured.u, plant.k_m, plant.max_current))
    return [dump_model_file(folder / MODEL_FILE, plant, joint, sample_rate=measured.rate)]


def write_diagnosis(folder: Path, predictor: Predictor, diag: Diagnosis, source: str, run: dict) -> dict:
    """Every file of a diagnosis in ``folder``; returns the diagnosis.json data."""
    data = diag.as_dict()  # holds no wall time: that goes to run.json
    files = [write_json(folder / "diagnosis.json", data)]
    labels = model_labels(len(diag.steps))
    structures = diag.models()
    files += write_model(folder, structures[-1], predictor.m)
    cmp = compare(predictor, dict(zip(labels, structures)))
    signal = worst_signal(diag.initial.nrmse_test, predictor.signals)
    overview = [labels[0], labels[-1]] if diag.steps else labels
    first_where = diag.steps[0].where if diag.steps else diag.final_where
    located = first_where.get("signals", {}).get(signal, {}).get("windows", [])
    files.append(plot_windows(cmp, signal, overview, folder / "heldout_windows.png"))
    files.append(plot_residual_time(cmp, signal, overview, folder / "residual.png", located))
    step_images = []
    final = data["final_model"]
    for k, step in enumerate(diag.steps, 1):
        path = folder / f"step{k}_{step.effect}.png"
        files.append(plot_evidence(step.effect, cmp, labels[k - 1], labels[k], step.where,
                                   step_values(data["steps"][k - 1], final), path, signal))
        step_images.append(path.name)
    located_all = {s: loc.get("windows", []) for s, loc in first_where.get("signals", {}).items()}
    files.append(write_rrd(folder / "traces.rrd", cmp, labels, f"diagnose {source}", located_all))
    index = folder / "index.html"
    run = {**run, "files": sorted([p.name for p in files] + [index.name, MARKER])}
    images = {"windows": "heldout_windows.png", "residual": "residual.png", "steps": step_images}
    index.write_text(diagnosis_page(data, images, source, run), encoding="utf-8")
    write_json(folder / MARKER, run)
    return data


def write_fit(folder: Path, predictor: Predictor, result: FitResult, initial: Structure, source: str,
              run: dict, floor: Floor) -> dict:
    """Every file of a fit in ``folder``, with the recording's ``floor`` (``diagnosis.floor.judged``)
    and whether the fit explains the recording to it; returns the fit.json data."""
    data = {**result.as_dict(), "noise_floor": floor.as_dict(), "explained": floor.explained(result.nrmse_test)}
    files = [write_json(folder / "fit.json", data), *write_model(folder, result.structure, predictor.m)]
    cmp = compare(predictor, {"initial": initial, "fitted": result.structure})
    signal = worst_signal(result.nrmse_test, predictor.signals)
    labels = ["initial", "fitted"]
    files.append(plot_windows(cmp, signal, labels, folder / "heldout_windows.png", rank_by="fitted"))
    files.append(plot_residual_time(cmp, signal, ["fitted"], folder / "residual.png"))
    files.append(write_rrd(folder / "traces.rrd", cmp, labels, f"fit {source}"))
    index = folder / "index.html"
    run = {**run, "files": sorted([p.name for p in files] + [index.name, MARKER])}
    index.write_text(fit_page(data, {"windows": "heldout_windows.png", "residual": "residual.png"},
                              source, run), encoding="utf-8")
    write_json(folder / MARKER, run)
    return data
