"""One fit of the interval coverage (scripts/interval_coverage.py): a case's truth recorded, its
TRUE structure fitted as ``mjjoint fit`` fits it, and each interval compared with the truth.

A parameter counts as identifiable in a fit when the fit does not call it poorly identifiable or
on a bound (``FitResult.warnings``; an interval widened by a bias still counts) and the fit
explains the recording to its noise floor (``diagnosis.floor``): a fit stuck in a local minimum
carries its miss in the parameters, and the diagnosis flags those intervals.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

from ..cli.fit import RESTARTS
from ..diagnosis.floor import noise_floor
from ..identify.effects import EFFECTS
from ..identify.fit import WIDENED, FitResult, check_intervals, fit
from ..identify.structure import Structure
from ..identify.windows import Measured, Predictor, WindowDesign
from ..recordings import read_recording
from .cases import GEAR_RATIO, Case, make_case
from .score import write_case_recording

CHECKS = ("own", "all", "none")


def covered(result: FitResult, truth: Structure, explained: bool) -> dict[str, tuple[bool, bool]]:
    """{parameter: (its interval holds the truth, it is identifiable in this fit)}."""
    flagged = {w.split(" ")[0] for w in result.warnings if WIDENED not in w}
    out = {}
    for name, (lo, hi) in result.intervals.items():
        out[name] = (lo <= truth.values[name] <= hi, explained and name not in flagged)
    return out


def coverage_fit(effect: str, seed: int, duration: float, truth_step: float | None = None, fit_iter: int = 30,
                 restarts: int = RESTARTS, check: str = "own") -> tuple[Case, FitResult, bool, float]:
    """(the case, its fit, whether the fit explains the recording, the fit's own rollouts) of
    ``effect``'s truth of ``seed`` recorded for ``duration`` [s] at ``truth_step`` (the model's
    own where None). ``check``: whose intervals are checked against the model and widened by
    their biases (``fit.check_intervals``): the effect's own parameters, every one, or none."""
    if check not in CHECKS:
        raise ValueError(f"check {check!r} is not one of {', '.join(CHECKS)}")
    case = make_case(effect, seed)
    with tempfile.TemporaryDirectory() as tmp:
        rec = read_recording(write_case_recording(case, Path(tmp), duration, truth_step), gear_ratio=GEAR_RATIO)
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=seed))
    start = Structure.create(case.truth.effects, case.truth.nominal, GEAR_RATIO, settings=case.truth.settings)
    result = fit(predictor, start, max_iter=fit_iter, restarts=restarts)
    fitted = result.rollouts
    if check != "none":
        own = [p.name for p in EFFECTS[effect].params]
        result = check_intervals(predictor, result, own if check == "own" else list(result.intervals),
                                 biased=list(result.intervals))
    explained = noise_floor(predictor, result.structure).explained(result.nrmse_test)
    return case, result, explained, fitted
