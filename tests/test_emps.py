"""EMPS (real linear drive): the reader, the published reference reproduced, and our fit next to it.

The recordings are not part of the repository: these tests skip with a message unless
``$MJJOINT_DATA`` (or <repo>/../shared/data) holds emps/ (see docs/datasets.md).
"""
from __future__ import annotations

import numpy as np
import pytest

from mjjoint.assets.drive import DriveSpec
from mjjoint.datasets.emps import (ESTIMATION, PUBLISHED, VALIDATION, equivalent_parameters,
                                   idim_least_squares, idim_relative_error, read_emps, sliding_friction,
                                   symmetric_equivalent)
from mjjoint.diagnosis.loop import diagnose
from mjjoint.datasets.paths import data_root
from mjjoint.identify.fit import fit
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import RecordingError

DATA = data_root() / "emps"
needs_data = pytest.mark.skipif(
    not all((DATA / f).is_file() for f in (ESTIMATION, VALIDATION)),
    reason=f"EMPS recordings not found in {DATA} (set MJJOINT_DATA to the folder holding emps/)")


@pytest.fixture(scope="module")
def estimation():
    return read_emps(DATA / ESTIMATION)


@needs_data
def test_reader_gives_force_in_newton_and_position_in_metres(estimation):
    rec = estimation.recording
    assert rec.n == 24841 and np.allclose(np.diff(rec.t), 1e-3, atol=1e-6)
    assert estimation.gtau == pytest.approx(35.15, rel=1e-3)
    assert -1e-3 < rec.q.min() and rec.q.max() < 0.3          # a 0.25 m stroke
    assert 50.0 < np.abs(rec.u).max() < 350.0                  # +-10 V at 35 N/V at most
    # Closed loop: the command pushes towards the reference (positive correlation).
    assert np.corrcoef(estimation.reference - rec.q, rec.u)[0, 1] > 0.3


@needs_data
def test_the_authors_procedure_reproduces_their_published_numbers(estimation):
    """Our IDIM-LS (their filters, decimation and regressors) gives their estimate and errors."""
    assert idim_least_squares(estimation.recording) == pytest.approx(PUBLISHED.as_vector(), rel=2e-3)
    assert idim_relative_error(estimation.recording, PUBLISHED.as_vector()) == pytest.approx(4.08, abs=0.01)
    validation = read_emps(DATA / VALIDATION).recording
    assert idim_relative_error(validation, PUBLISHED.as_vector()) == pytest.approx(5.98, abs=0.01)


@pytest.fixture(scope="module")
def our_fit(estimation):
    """(M, Fv, Fc, offset) of the published structure fitted by windowed prediction."""
    pred = Predictor(Measured.from_recording(estimation.recording, 1.0, output=False), WindowDesign())
    start = Structure.create(("coulomb_friction", "viscous_friction", "input_offset"), DriveSpec(), 1.0)
    return equivalent_parameters(fit(pred, start, max_iter=20).structure)[:4]  # this structure has no Fa


@needs_data
def test_output_error_fit_lands_next_to_the_published_inverse_model(estimation, our_fit):
    """Fitting the published structure by windowed prediction (not by inverse dynamics) gives the
    same mass within 5 % and Fc, Fv, offset within 10 % (measured: -2, -5, +6, +9 %: short of the
    issue's 5 % because the two costs weight a model error differently, see the next tests and
    docs/datasets.md), and the authors' own force error within 0.5 points of theirs, which is the
    least-squares optimum of that very error, on both files (measured: 4.50 vs 4.08 % and 5.91
    vs 5.98 %). That error pairs each sample's force with the motion at its instant; the
    simulation holds it over the period after (``sim.held_controls``), half a sample later."""
    ours, pub = our_fit, PUBLISHED.as_vector()
    assert ours[0] == pytest.approx(pub[0], rel=0.05)
    assert ours[1:] == pytest.approx(pub[1:], rel=0.10)
    assert idim_relative_error(estimation.recording, ours) < PUBLISHED.error_estimation + 0.5
    validation = read_emps(DATA / VALIDATION).recording
    assert idim_relative_error(validation, ours) < PUBLISHED.error_validation + 0.5


@needs_data
def test_steady_sliding_friction_is_steeper_backwards_on_both_files(estimation):
    """The real friction is not the symmetric Coulomb-viscous line both fits assume: on the
    constant-speed plateaus its slope is ~155-165 N s/m forwards and ~230-240 N s/m backwards,
    with equal levels at zero speed. So a symmetric model's Fv and offset depend on how a cost
    weights the speeds (offset ~ -(slope difference / 2) x typical speed)."""
    for rec in (estimation.recording, read_emps(DATA / VALIDATION).recording):
        fric = sliding_friction(rec, PUBLISHED.mass)
        (up, level_up), (down, level_down) = fric[1], fric[-1]
        assert down > 1.3 * up > 0
        assert level_up > 15.0 and abs(level_up + level_down) < 1.0   # Coulomb levels: equal, opposite


@needs_data
def test_the_gap_to_the_published_fit_is_the_slow_samples(estimation, our_fit):
    """Why ours and IDIM-LS differ: near the reversals (|v| < 3 cm/s, 9 % of the decimated
    samples) the measured friction lies well below the Coulomb-viscous line; the force cost
    bends Fc down and Fv up to chase it, the windowed position cost barely sees it (a short
    force error moves the carriage little). Drop those samples from the authors' own least
    squares and every parameter moves towards ours, to within 3 % (measured: -0.8, -1.1, +1.8,
    -1.6 %). Not an artefact of our plant (sign regularisation, timestep, window start)."""
    full = idim_least_squares(estimation.recording)
    sliding = idim_least_squares(estimation.recording, min_speed=0.03)
    assert our_fit == pytest.approx(sliding, rel=0.03)
    assert np.all(np.abs(our_fit - sliding)[1:] < np.abs(our_fit - full)[1:])


def test_a_file_that_is_not_emps_fails_in_one_line(tmp_path):
    import scipy.io
    path = tmp_path / "other.mat"
    scipy.io.savemat(path, {"t": np.arange(10.0), "qm": np.zeros(10)})
    with pytest.raises(RecordingError, match="not an EMPS file: variable 'vir' is missing"):
        read_emps(path)
    with pytest.raises(RecordingError, match="no such file"):
        read_emps(tmp_path / "absent.mat")


@pytest.fixture(scope="module")
def diagnosed(estimation):
    """The diagnosis from the carriage mass alone (scripts/emps_diagnose.py's), its final model."""
    pred = Predictor(Measured.from_recording(estimation.recording, 1.0, output=False), WindowDesign())
    return diagnose(pred, Structure.create((), DriveSpec(), 1.0))


@needs_data
def test_the_diagnosis_names_the_direction_dependent_viscous_slope(estimation, diagnosed):
    """From a rigid mass, the diagnosis names viscous and Coulomb friction and then the viscous
    asymmetry, not an offset. Its two slopes are the ones the constant-speed plateaus show
    (measured independently, ``sliding_friction``: 155 / 231 N s/m), within 5 %."""
    assert "viscous_asymmetry" in diagnosed.missing and "input_offset" not in diagnosed.missing
    m, fv, fc, offset, fa = equivalent_parameters(diagnosed.final.structure)
    plateaus = sliding_friction(estimation.recording, PUBLISHED.mass)
    assert fv + fa == pytest.approx(plateaus[1][0], rel=0.05)
    assert fv - fa == pytest.approx(plateaus[-1][0], rel=0.05)
    assert offset == 0.0


@needs_data
def test_the_diagnosed_model_meets_the_published_one_on_its_own_terms(estimation, diagnosed):
    """Issue 5: in the published model's terms (the symmetric model closest to ours along the
    estimation file: what the authors' IDIM-LS would give if the force were ours), every
    parameter is within 5 % of the published one (measured: 0.0, -4.2, +4.4, -4.5 %), and the
    authors' relative force error is lower than theirs on both files (3.21 vs 4.08 %, 5.35 vs
    5.98 %). The published offset is what the asymmetry looks like to a symmetric model: the
    authors' own least squares with the |v| regressor added puts it at -0.24 N."""
    ours = equivalent_parameters(diagnosed.final.structure)
    assert symmetric_equivalent(estimation.recording, ours) == pytest.approx(PUBLISHED.as_vector(), rel=0.05)
    validation = read_emps(DATA / VALIDATION).recording
    assert idim_relative_error(estimation.recording, ours) < PUBLISHED.error_estimation
    assert idim_relative_error(validation, ours) < PUBLISHED.error_validation
    assert abs(idim_least_squares(estimation.recording, asymmetric=True)[3]) < 0.1 * abs(PUBLISHED.offset)


@needs_data
@pytest.mark.slow
def test_the_command_line_alone_names_the_direction_dependent_viscous_slope(estimation, tmp_path):
    """docs/datasets.md's command (no script): the same three effects, no offset, and the two
    slopes the constant-speed plateaus show, within 5 %, in the recording's own units."""
    import json

    from mjjoint.cli import main
    out = tmp_path / "emps_cli"
    assert main(["diagnose", str(DATA / ESTIMATION), "--plant", "linear", "--columns", "t=t,u=vir,q=qm,theta=qm",
                 "--scales", "u=35.15065188", "--out", str(out)]) == 0
    d = json.loads((out / "diagnosis.json").read_text())
    assert "viscous_asymmetry" in d["missing"] and "input_offset" not in d["missing"]
    values = d["final_model"]["parameters"]
    sigma, r = values["viscous_friction.sigma"], values["viscous_asymmetry.ratio"]
    plateaus = sliding_friction(estimation.recording, PUBLISHED.mass)
    assert sigma * (1 + r) == pytest.approx(plateaus[1][0], rel=0.05)
    assert sigma * (1 - r) == pytest.approx(plateaus[-1][0], rel=0.05)
