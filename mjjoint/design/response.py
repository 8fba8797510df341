"""Rivals' responses to a candidate input, as the decision will see them.

The decision (``design.decide``) refits both rivals to the new recording and scores them by
windowed prediction (``identify.windows``): each 0.25 s window starts from the measured state
and is predicted open loop. So the design scores them the same way: each rival's fitted model
is run under the input (the run is also what the limits are checked on), and that run is taken
as the recording in whose windows both rivals, their parameter draws, and the other rival with
each parameter stepped (its sensitivities, for the refit) are predicted (``Windowed``). A free-run difference would
count drift that the windows never see (docs/design-experiments.md: 406 032 nats promised for
an input whose recording the refitted rivals predicted within 1.6 % of each other).

Models are compiled once per rival (the search evaluates dozens of inputs on the same
models). A draw the explicit scheme cannot step stably is left out; an input under which a
rival's run diverges is infeasible (``Diverged``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..identify.windows import Measured, Predictor, WindowDesign
from ..rehearse import Controller
from ..sim import Simulator, Trace
from .loop import loop_trace
from .rivals import Rival


# Parameter steps of the sensitivities (optimiser coordinates): log parameters by FD_LOG (1 %),
# linear ones by FD_LINEAR of their range; small enough for a linear response, large enough that
# the windowed predictions (float64, ~1e-12 relative) resolve them.
FD_LOG = 0.01
FD_LINEAR = 1e-3


class Diverged(ValueError):
    """A rival's simulation blew up under the candidate input."""


class RivalModel:
    """A rival's compiled fitted model at ``rate`` and ``ndraws`` parameter draws about it,
    run open loop (a torque programme) or, with ``loop`` (a controller), tracking a link-angle
    reference (``design.loop``)."""

    def __init__(self, rival: Rival, rate: float, ndraws: int = 4, seed: int = 0, loop: Controller | None = None,
                 limit_draws: int = 0):
        self.rival, self.loop, self.rate = rival, loop, rate
        self.fitted = Simulator(rival.structure.compile(), sample_rate=rate)
        self.draws, self._draw_sims = self._compiled(rival.draws(ndraws, seed), rate)
        # Every parameter drawn (``Rival.joint_draws``): runs for the limits only.
        self._limit_sims = self._compiled(rival.joint_draws(limit_draws, seed + 1), rate)[1]

    @staticmethod
    def _compiled(structures, rate: float) -> tuple[list, list[Simulator]]:
        kept, sims = [], []
        for s in structures:
            try:
                model = s.compile()
            except ValueError:  # unstable at the timestep: no prediction to spread, no run
                continue
            kept.append(s)
            sims.append(Simulator(model, sample_rate=rate))
        return kept, sims

    def _run(self, sim: Simulator, x: np.ndarray) -> Trace:
        if self.loop is None:
            return sim.run(x)
        return loop_trace(sim.model, x, self.loop, self.rate, self.rival.structure.gear_ratio)

    def run(self, x: np.ndarray) -> Trace:
        """The fitted model's run under ``x``: the torque, or the reference in closed loop."""
        try:
            return self._run(self.fitted, x)
        except ValueError as exc:
            raise Diverged(f"{self.rival.effect}: {exc}") from None

    def draw_runs(self, x: np.ndarray) -> list[Trace]:
        """The parameter draws' runs under ``x``, the effect's and every parameter's (for the
        limits: the joint may be any of them); a draw whose run diverges is left out, as one that
        cannot be compiled is."""
        runs = []
        for sim in (*self._draw_sims, *self._limit_sims):
            try:
                runs.append(self._run(sim, x))
            except ValueError:
                continue
        return runs


@dataclass
class Windowed:
    """Both rivals' windowed predictions in the run of rival ``truth`` (cost samples only, as
    windows x samples per signal): each fitted model's, the variance of its draws' about it,
    and the other rival's sensitivities (one prediction per parameter, stepped by ``steps`` in
    the optimiser's coordinates); ``samples``: the run's sample index of each; ``holdout``: the
    windows a decision on this run compares (the fits' held-out split)."""

    truth: int
    samples: np.ndarray
    mean: tuple[dict[str, np.ndarray], dict[str, np.ndarray]]
    var: tuple[dict[str, np.ndarray], dict[str, np.ndarray]]
    stepped: list[dict[str, np.ndarray]]
    steps: np.ndarray
    holdout: np.ndarray | None = None


def sensitivity_steps(structure) -> tuple[list, np.ndarray]:
    """Finite-difference steps of every parameter: 1 % of a log parameter, 1e-3 of a linear one's
    range, taken inwards at a bound. Returns (stepped structures, signed steps)."""
    x = structure.vector()
    lo, hi = structure.bounds()
    out, steps = [], []
    for j, p in enumerate(structure.params):
        h = FD_LOG if p.log else FD_LINEAR * (hi[j] - lo[j])
        h = h if x[j] + h <= hi[j] else -h
        y = x.copy()
        y[j] += h
        out.append(structure.from_vector(y))
        steps.append(h)
    return out, np.asarray(steps)


def windowed(models: tuple[RivalModel, RivalModel], trace: Trace, truth: int, window: WindowDesign) -> Windowed:
    """Predict both rivals, their draws and the other rival's parameter steps in the windows of
    ``trace``, rival ``truth``'s run: the predictions a refit to that recording starts from."""
    predictor = Predictor(Measured.from_recording(trace, trace.gear_ratio), window, nthread=1)
    other = models[1 - truth].rival.structure
    stepped, steps = sensitivity_steps(other)
    groups = [[m.rival.structure, *m.draws] for m in models]
    preds = predictor.predict([s for g in groups for s in g] + stepped)
    cols, keep = predictor.cols, predictor.signals
    pick = lambda p: {s: p[s][:, cols] for s in keep}  # noqa: E731
    means, vars_ = [], []
    k = 0
    for g in groups:
        own = pick(preds[k])
        drawn = [pick(p) for p in preds[k + 1:k + len(g)]]
        k += len(g)
        means.append(own)
        vars_.append({s: (np.nanmean([(d[s] - own[s]) ** 2 for d in drawn], axis=0) if drawn
                          else np.zeros_like(own[s])) for s in keep})
    return Windowed(truth, predictor.samples[:, cols], tuple(means), tuple(vars_),
                    [pick(p) for p in preds[k:]], steps, np.asarray(predictor.holdout, bool))
