"""A fit with restarts also runs staged (``identify.fit.fit``): the effects that refine another
held while the rest are fitted, then all from there."""
from __future__ import annotations

import tempfile
from pathlib import Path

import pytest

from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.benchmark.score import write_case_recording
from mjjoint.diagnosis.floor import noise_floor
from mjjoint.identify.effects import EFFECTS
from mjjoint.identify.fit import fit, refinements
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import read_recording


def _start(truth: Structure) -> Structure:
    """The true structure at the catalogue's initial values."""
    return Structure.create(truth.effects, truth.nominal, GEAR_RATIO, settings=truth.settings)


def test_the_refinements_are_the_parameters_of_effects_that_require_another():
    start = _start(make_case("dynamic_friction", 0).truth)
    held = refinements(start)
    assert {"dynamic_friction.k", "dynamic_friction.b"} <= held
    for e in start.effects:
        own = {p.name for p in EFFECTS[e].params}
        assert (own <= held) if EFFECTS[e].requires else not (own & held), e
    assert "coulomb_friction.fc" not in held


def test_a_2sep_fit_from_the_catalogue_values_finds_the_truth_staged():
    """Concealed dynamic_friction seed 0 (8 s): fitted at once from the catalogue's values the
    pre-sliding stiffness ends near 306 (truth 785) and delta misses at NRMSE 0.08 against a floor
    near 0.01; staged, the fit explains the recording and both 2SEP gains are within 10 %."""
    case = make_case("dynamic_friction", 0)
    start, truth = _start(case.truth), case.truth
    with tempfile.TemporaryDirectory() as tmp:
        rec = read_recording(write_case_recording(case, Path(tmp), 8.0), gear_ratio=GEAR_RATIO)
    predictor = Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=0))
    result = fit(predictor, start, restarts=1)
    assert noise_floor(predictor, result.structure).explained(result.nrmse_test), result.nrmse_test
    for name in ("dynamic_friction.k", "dynamic_friction.b"):
        assert result.structure.values[name] == pytest.approx(truth.values[name], rel=0.1), name
    assert result.starts >= 2
