"""A flexible link's lead-ins of several models run in one rollout call per sample
(Predictor._flexible_start): each model's predictions are those it gets alone, bit for bit."""
from __future__ import annotations

import numpy as np

from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import Recording
from mjjoint.rehearse import LabProgram, record


def test_flexible_lead_ins_run_together_predict_as_each_alone():
    truth = make_case("none", 0).truth
    cols = record(*truth.model_params(), LabProgram(duration=3.0, seed=0))
    pred = Predictor(Measured.from_recording(Recording(gear_ratio=GEAR_RATIO, meta={}, **cols), GEAR_RATIO),
                     WindowDesign(seed=0))
    rods = [truth.with_effect("link_flexibility", {"link_flexibility.ei": ei}) for ei in (300.0, 800.0)]
    windows = np.arange(2, 7)  # past the first FLEX_LEAD of the recording: every one leads in
    calls = []
    real = pred._flexible_start
    pred._flexible_start = lambda jobs: calls.append(len(jobs)) or real(jobs)
    together = pred.predict(rods, windows)
    alone = [pred.predict([r], windows)[0] for r in rods]
    assert calls == [2, 1, 1]
    for a, b in zip(together, alone):
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])
    # The lead-in moved the segments: a straight rod at the starts predicts otherwise.
    pred._flexible_start = lambda jobs: None
    straight = pred.predict(rods[:1], windows)[0]
    assert not np.array_equal(straight["delta"], alone[0]["delta"])
