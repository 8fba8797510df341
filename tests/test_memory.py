"""Memory of predictions on long recordings (issue 21: a 10-minute recording within 1 GB).

Two properties, each with the exactness it must keep: the free run (the noise floor's twin) is
rolled out in stretches, and a batch's predictions are reduced to residual columns one model at
a time; both give the one-piece results bit for bit, and what they hold at once does not grow
with the recording (free run) or with the models of a batch (residuals)."""
from __future__ import annotations

import tracemalloc
import weakref

import numpy as np
import pytest

import mjjoint.identify.windows as windows_mod
from mjjoint.benchmark.cases import GEAR_RATIO, make_case
from mjjoint.identify.fit import residual_matrix
from mjjoint.identify.windows import Measured, Predictor, WindowDesign
from mjjoint.recordings import Recording
from mjjoint.rehearse import LabProgram, record

SMALL = 2 ** 18  # a rollout buffer that splits every batch and run below into many chunks


@pytest.fixture(scope="module")
def case():
    return make_case("backlash", 0)


def _predictor(case, duration: float) -> Predictor:
    cols = record(*case.truth.model_params(), LabProgram(duration=duration, seed=0))
    rec = Recording(gear_ratio=GEAR_RATIO, meta={}, **cols)
    return Predictor(Measured.from_recording(rec, GEAR_RATIO), WindowDesign(seed=0))


def _peak_mb(f) -> tuple[float, object]:
    """(traced peak above the start [MB], result) of f(): numpy's buffers are traced."""
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        out = f()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return (peak - base) / 2 ** 20, out


def test_free_run_in_stretches_is_the_one_rollout_bit_for_bit(case, monkeypatch):
    pred = _predictor(case, 4.0)
    structures = [case.truth, case.truth.with_values({"backlash.width": 2 * case.truth.values["backlash.width"]})]
    whole = [pred.free_run(s) for s in structures]  # one stretch: the buffer holds the whole run
    monkeypatch.setattr(windows_mod, "ROLLOUT_BUFFER", SMALL)
    for s, one in zip(structures, whole):
        split = pred.free_run(s)
        for k in one:
            np.testing.assert_array_equal(split[k], one[k])
    assert not np.array_equal(whole[0]["delta"], whole[1]["delta"])  # the runs depend on the model


def test_free_run_memory_does_not_grow_with_the_recording(case, monkeypatch):
    """Beyond its four output signals the run holds a buffer's worth of states, not the whole
    run's (672 B a sample of the shipped arm, with copies ~1.3 kB)."""
    monkeypatch.setattr(windows_mod, "ROLLOUT_BUFFER", SMALL)
    held = {}
    for duration in (3.0, 9.0):
        pred = _predictor(case, duration)
        pred.free_run(case.truth)  # compiled and cached before measuring
        held[duration] = _peak_mb(lambda: pred.free_run(case.truth))[0]
        samples = len(pred.m.t)
        held[duration] = (held[duration], samples)
    (short, n_short), (long_, n_long) = held[3.0], held[9.0]
    per_sample = (long_ - short) * 2 ** 20 / (n_long - n_short)
    assert per_sample < 200, f"{per_sample:.0f} B per sample"


def test_residual_columns_streamed_equal_each_model_alone(case, monkeypatch):
    """A Jacobian-like batch through ``residual_matrix``, its rollouts chunked across model
    boundaries, gives each column exactly the residuals of that model predicted alone."""
    pred = _predictor(case, 4.0)
    names = ["backlash.width", "coulomb_friction.fc"]
    x0 = case.truth.vector(names)
    x = x0[:, None] * np.array([[1.0, 1.01, 1.0], [1.0, 1.0, 0.99]])
    w = pred.train
    alone = np.stack([pred.residuals(pred.predict([case.truth.from_vector(x[:, i], names)], w)[0], w)
                      for i in range(x.shape[1])], axis=1)
    monkeypatch.setattr(windows_mod, "ROLLOUT_BUFFER", SMALL)
    seen: dict = {}
    r = residual_matrix(lambda s, win: pred.predictions(s, win), case.truth, names, w, pred, seen)(x)
    np.testing.assert_array_equal(r, alone)
    assert not seen  # kept only for a single vector's evaluation
    r1 = residual_matrix(lambda s, win: pred.predictions(s, win), case.truth, names, w, pred, seen)(x[:, 0])
    np.testing.assert_array_equal(r1[:, 0], alone[:, 0])
    np.testing.assert_array_equal(seen["x"], x[:, 0])


def test_a_batch_holds_one_models_predictions_at_a_time(case, monkeypatch):
    """Reducing a batch of models to residual columns holds one model's predictions at a time:
    when a model's predictions are made, those of the models before it are gone."""
    monkeypatch.setattr(windows_mod, "ROLLOUT_BUFFER", SMALL)
    pred = _predictor(case, 4.0)
    names = ["coulomb_friction.fc"]
    grid = case.truth.vector(names)[:, None] * np.linspace(0.9, 1.1, 6)[None, :]
    made, alive = [], []

    def watched(structures, w):
        for p in pred.predictions(structures, w):
            alive.append(sum(ref() is not None for ref in made))
            made.append(weakref.ref(p["q"]))
            yield p
            del p
    r = residual_matrix(watched, case.truth, names, pred.train, pred)(grid)
    assert r.shape[1] == 6 and len(made) == 6
    assert alive == [0] * 6


def _resident_mb() -> float:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


@pytest.mark.skipif(windows_mod._MALLOC_TRIM is None, reason="glibc's allocator only")
def test_freed_arrays_of_a_few_mb_leave_the_resident_memory():
    """Once glibc's mapping threshold has risen past a few MB, freed arrays of that size stay
    resident until ``release_freed`` hands their pages back."""
    raised = np.ones(2 ** 20)  # 8 MB, mapped; freeing it raises the threshold past 4 MB
    del raised
    arrays = [np.ones(2 ** 19) for _ in range(40)]  # 40 x 4 MB from the heap
    last = arrays[-1]  # kept: the heap's top stays in use, so only pages inside it can go back
    del arrays
    before = _resident_mb()
    windows_mod.release_freed()
    assert before - _resident_mb() > 100
    assert last.sum() == 2 ** 19
