"""Rivals' responses to a candidate input, as the decision will see them.

The decision (``design.decide``) scores rivals by windowed prediction (``identify.windows``):
each 0.25 s window starts from the measured state and is predicted open loop. So the design
scores them the same way: each rival's fitted model is run under the input (the run is also
what the limits are checked on), and that run is taken as the recording in whose windows both
rivals, and their parameter draws, are predicted (``Windowed``). A free-run difference would
count drift that the windows never see: on the offset/asymmetry pair the free runs parted by
tens of thousands of nats under inputs whose recordings the windowed fits could not tell apart.

Models are compiled once per rival (the search evaluates dozens of inputs on the same
models). A draw the explicit scheme cannot step stably is left out; an input under which a
rival's run diverges is infeasible (``Diverged``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..identify.windows import Measured, Predictor, WindowDesign
from ..sim import Simulator, Trace
from .rivals import Rival


class Diverged(ValueError):
    """A rival's simulation blew up under the candidate input."""


class RivalModel:
    """A rival's compiled fitted model at ``rate`` and ``ndraws`` parameter draws about it."""

    def __init__(self, rival: Rival, rate: float, ndraws: int = 4, seed: int = 0):
        self.rival = rival
        self.fitted = Simulator(rival.structure.compile(), sample_rate=rate)
        self.draws = []
        for s in rival.draws(ndraws, seed):
            try:
                s.compile()
            except ValueError:  # unstable at the timestep: no prediction to spread
                continue
            self.draws.append(s)

    def run(self, u: np.ndarray) -> Trace:
        try:
            return self.fitted.run(u)
        except ValueError as exc:
            raise Diverged(f"{self.rival.effect}: {exc}") from None


@dataclass
class Windowed:
    """Both rivals' windowed predictions in the run of rival ``truth`` (cost samples only, as
    windows x samples per signal): each fitted model's, and the variance of its draws' about it;
    ``samples``: the run's sample index of each."""

    truth: int
    samples: np.ndarray
    mean: tuple[dict[str, np.ndarray], dict[str, np.ndarray]]
    var: tuple[dict[str, np.ndarray], dict[str, np.ndarray]]


def windowed(models: tuple[RivalModel, RivalModel], trace: Trace, truth: int, window: WindowDesign) -> Windowed:
    """Predict both rivals (and their draws) in the windows of ``trace``, rival ``truth``'s run."""
    predictor = Predictor(Measured.from_recording(trace, trace.gear_ratio), window, nthread=1)
    groups = [[m.rival.structure, *m.draws] for m in models]
    preds = predictor.predict([s for g in groups for s in g])
    cols = predictor.cols
    means, vars_ = [], []
    k = 0
    for g in groups:
        own = {s: p[:, cols] for s, p in preds[k].items() if s in predictor.signals}
        drawn = preds[k + 1:k + len(g)]
        k += len(g)
        means.append(own)
        vars_.append({s: (np.nanmean([(d[s][:, cols] - own[s]) ** 2 for d in drawn], axis=0) if drawn
                          else np.zeros_like(own[s])) for s in own})
    return Windowed(truth, predictor.samples[:, cols], tuple(means), tuple(vars_))
