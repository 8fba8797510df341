"""The design criterion: the expected log-likelihood ratio between two rivals' predictions.

With each measured sample y_s(t) Gaussian about rival A's prediction, of variance
S_s(t) = sigma_s^2 (the noise floor: ``prediction_floor``) + v_A,s(t) + v_B,s(t) (each rival's
prediction variance from its parameter uncertainty), the log-likelihood ratio of A over B has the
expectation

    D_A = 1/2 sum_s sum_t (y_A,s(t) - y_B,s(t))^2 / S_s(t)

when A is true. The predictions are the windowed ones the decision compares
(``response.windowed``), in A's run for D_A and in B's for D_B; D is the smaller: the
experiment must separate the rivals whichever is true (docs/design-experiments.md). D in
nats: D = 3 makes the true rival 20 times as likely. Where the rivals differ by less than
their combined spread, a sample counts little however large the difference.

The decision refits B to the new recording, so y_B is B after that refit, linearised: the
difference left once B's parameter sensitivities (whitened like the difference) have taken out
all they can, by least squares (T-optimality, Atkinson and Fedorov 1975, with the rivals'
spread in the metric). Without it, D rewarded inputs whose difference a refit of the shared
parameters absorbs: on the offset/asymmetry pair (truth asymmetric) the design promised
406 032 nats and the refitted rivals' held-out costs on its recording differed by 1.6 %.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..identify.windows import Measured, Predictor, WindowDesign
from ..rehearse.sensors import Sensors
from .limits import PREDICTED
from .record import logged
from .response import Windowed

# Singular values below RCOND of the largest are directions the refit cannot resolve.
RCOND = 1e-8


def prediction_floor(predictor: Predictor, structures, windows=None) -> dict[str, float]:
    """The noise floor of each predicted signal (q, delta, tau) on this recording: the rms error
    of the better of ``structures`` over ``windows`` (default the held-out ones). Not the
    sensors' noise alone: a window's prediction also carries its start state's error (the
    velocity is a derivative of quantised angles) through the window, and that is what the
    decision's costs are made of."""
    test, cols = (predictor.test if windows is None else np.asarray(windows)), predictor.cols
    preds = predictor.predict(list(structures), test)
    return {s: float(min(np.sqrt(np.nanmean((p[s][:, cols] - predictor.meas[s][test][:, cols]) ** 2))
                         for p in preds)) for s in predictor.signals}


def input_floor(models, traces, window: WindowDesign = WindowDesign(),
                sensors: Sensors = Sensors()) -> dict[str, float]:
    """The noise floor of the recording a candidate input would give: each rival's run of it
    (``traces``) logged by the lab's sensors and predicted by that rival itself in every window,
    the rms error per signal; the two rivals' combined as the root of their mean square. The
    floor depends on the motion: the same joint's windowed q prediction errs by ~1e-4 rad under
    a slow sine and by ~0.05 rad in fast one-way rotation (its start velocity's error grows
    with speed), so a floor measured on the original recording mis-weighs a different input
    (docs/design-experiments.md)."""
    floors = []
    for k, (m, tr) in enumerate(zip(models, traces)):
        rec = logged(tr, replace(sensors, seed=sensors.seed + k))
        predictor = Predictor(Measured.from_recording(rec, tr.gear_ratio), window, nthread=1)
        floors.append(prediction_floor(predictor, [m.rival.structure], np.arange(len(predictor.starts))))
    return {s: float(np.sqrt(np.mean([f[s] ** 2 for f in floors]))) for s in floors[0]}


def predicted_noise(noise: dict[str, float], gear_ratio: float) -> dict[str, float]:
    """The noise std of the predicted signals from the recorded ones' (q, theta, tau; given by the
    user): delta's from theta's and q's, taken as independent."""
    out = {"q": noise["q"], "delta": float(np.hypot(noise.get("theta", 0.0), noise["q"] / gear_ratio))}
    if "tau" in noise:
        out["tau"] = noise["tau"]
    return out


def separation(w: Windowed, floor: dict[str, float], signals) -> dict[str, np.ndarray]:
    """Per signal and cost sample, the squared difference between the true rival's prediction and
    the other's after its linearised refit, in combined spreads (module doc); ``floor``: the
    noise std of each predicted signal (q, delta, tau)."""
    truth, other = w.truth, 1 - w.truth
    names = [PREDICTED[u] for u in signals]
    root = {s: np.sqrt(max(floor[s], 1e-12) ** 2 + w.var[0][s] + w.var[1][s]) for s in names}
    d = np.concatenate([((w.mean[other][s] - w.mean[truth][s]) / root[s]).ravel() for s in names])
    jac = np.stack([np.concatenate([((p[s] - w.mean[other][s]) / root[s]).ravel() for s in names]) / h
                    for p, h in zip(w.stepped, w.steps)], axis=1)
    # A parameter whose step makes the rival unstable (NaN predictions) gives no direction.
    jac = jac[:, np.all(np.isfinite(jac[np.isfinite(d)]), axis=0)]
    ok = np.isfinite(d)
    e = np.zeros_like(d)
    e[ok] = d[ok] - _projection(jac[ok], d[ok])
    sizes = np.cumsum([0] + [w.mean[truth][s].size for s in names])
    shape = w.mean[truth][names[0]].shape
    return {u: (e[a:b] ** 2).reshape(shape) for u, a, b in zip(signals, sizes[:-1], sizes[1:])}


def _projection(jac: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The part of d the columns of jac reproduce (least squares, columns scaled to unit norm so
    that a parameter's units do not decide which directions count as resolved)."""
    norms = np.linalg.norm(jac, axis=0)
    cols = norms > 0
    if not cols.any():
        return np.zeros_like(d)
    a = jac[:, cols] / norms[cols]
    coef, *_ = np.linalg.lstsq(a, d, rcond=RCOND)
    return a @ coef


def discrimination(ws: list[Windowed], floor: dict[str, float], signals) -> float:
    """D: the expected log-likelihood ratio between the rivals [nats] once the wrong one has been
    refitted, the smaller of its two values (either rival true)."""
    return float(min(0.5 * sum(v.sum() for v in separation(w, floor, signals).values()) for w in ws))
