"""Several recordings in one fit or diagnosis: separate segments, never one fake continuous run.

Two runs of the same joint, one driven in the positive and one in the negative direction
(2SEP friction, whose history and lead-in matter most at a start), are stacked. The stacked
windows predict exactly what each run's own windows predict, no window spans the join, and
`mjjoint fit A B` gives the fit of the stacked recordings.
"""
from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pytest

from mjjoint.assets import ArmSpec
from mjjoint.cli import main
from mjjoint.excitation import Multisine
from mjjoint.identify.fit import fit
from mjjoint.identify.structure import Structure
from mjjoint.cli.fit import RESTARTS
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.problem import Inputs, load_problem
from mjjoint.recordings import read_recording
from mjjoint.sim import Simulator

GEAR = 160.0
NOMINAL = ArmSpec(segments=0, gravity=0.0)
EFFECTS = ("linear_stiffness", "transmission_damping", "coulomb_friction", "dynamic_friction")
VALUES = {"linear_stiffness.k1": 1e4, "transmission_damping.d": 2.0, "coulomb_friction.fc": 0.02}
TRUTH = Structure.create(EFFECTS, NOMINAL, GEAR, VALUES)
# With a delay, a window at a join would reach back into the previous run's input.
DELAYED = Structure.create((*EFFECTS, "input_delay"), NOMINAL, GEAR, {**VALUES, "input_delay.delay": 4e-3})
DESIGN = WindowDesign(length=0.1, lead=0.2)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> list[Path]:
    d = tmp_path_factory.mktemp("runs")
    arm, joint = TRUTH.model_params()
    paths = []
    for k, sign in enumerate((1.0, -1.0, 1.0)):
        u = sign * 0.04 + Multisine(amplitude=0.03, f_min=1.0, f_max=20.0, seed=k).sample(1000.0, 1.5)
        paths.append(Simulator(arm=arm, joint=joint).run(u).to_csv(d / f"run{k}.csv"))
    return paths


def measured(path: Path) -> Measured:
    return Measured.from_recording(read_recording(path, gear_ratio=GEAR), GEAR)


def test_stacked_windows_predict_what_each_run_predicts(runs):
    # Two positive runs in a row: the second starts at q = 0 after the first ended far up, a jump
    # back that a history run across the join would take for a negative motion.
    parts = [measured(runs[k]) for k in (0, 2, 1)]
    alone = [Predictor(m, DESIGN, nthread=1) for m in parts]
    both = Predictor(Measured.stack(parts), DESIGN, nthread=1)
    joins = np.cumsum([len(m.t) for m in parts])[:-1]
    assert both.m.joins == tuple(joins)
    # Each run is tiled afresh from its start (a run that is not the last may end in one more window).
    own = np.concatenate([p.starts + offset for p, offset in zip(alone, [0, *joins])])
    common = np.flatnonzero(np.isin(both.starts, own))
    np.testing.assert_array_equal(both.starts[common], own)
    assert len(both.starts) - len(own) <= len(joins)
    n = both.nwin_samples
    for join in joins:
        assert not np.any((both.starts < join) & (both.starts + n > join))  # no window spans a join
    for model in (TRUTH, DELAYED):
        (stacked,) = both.predict([model], common)
        per_run = [p.predict([model])[0] for p in alone]
        for s in ("q", "delta", "tau"):
            expected = np.concatenate([r[s] for r in per_run])
            scale = np.ptp(expected)
            np.testing.assert_allclose(stacked[s], expected, rtol=0, atol=1e-6 * scale, err_msg=s)
    # The same samples as one continuous run (no join) would put a window across the boundary and
    # carry the first run's friction history into the second's start.
    glued = Predictor(Measured(**{**vars(Measured.stack(parts)), "joins": ()}), DESIGN, nthread=1)
    assert np.any((glued.starts < joins[0]) & (glued.starts + n > joins[0]))


def test_fit_of_two_files_is_the_fit_of_the_stacked_recordings(runs, tmp_path):
    args = ["--gear-ratio", str(GEAR), "--base", ",".join(EFFECTS), "--window-length", "0.1",
            "--lead-in", "0.2", "--max-iter", "3"]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(["fit", *map(str, runs[:2]), *args, "--out", str(tmp_path / "fit")]) == 0
    got = json.loads((tmp_path / "fit" / "fit.json").read_text())["structure"]["parameters"]
    run = json.loads((tmp_path / "fit" / "run.json").read_text())
    assert run["arguments"]["recording"] == [str(p) for p in runs[:2]]
    # The same problem from Python: the two recordings stacked, started from their initial values.
    problem = load_problem(list(runs[:2]), Inputs(gear_ratio=GEAR, base=EFFECTS, design=DESIGN))
    np.testing.assert_array_equal(problem.predictor.m.q, Measured.stack([measured(p) for p in runs[:2]]).q)
    assert problem.predictor.m.joins == Measured.stack([measured(p) for p in runs[:2]]).joins
    want = fit(problem.predictor, problem.base, max_iter=3, restarts=RESTARTS).structure.values
    assert got == pytest.approx(want, rel=1e-9)


def test_a_multi_joint_recording_is_not_stacked(runs, tmp_path, capsys):
    multi = tmp_path / "arm.csv"
    multi.write_text("t,u1,q1,theta1,u2,q2,theta2\n" + "".join(f"{i * 1e-3},0,0,0,0,0,0\n" for i in range(3000)))
    code = main(["fit", str(runs[0]), str(multi), "--gear-ratio", "160", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and "holds several joints; only single-joint recordings are stacked" in err
