"""After the designed experiment: which rival does the new recording support?

Both rivals are refitted (every parameter, from their fits to the original recording and
from the effect's default values beside them: ``refit``) to the
new recording by windowed prediction error (``identify.fit``), and compared on the windows the
fits did not see. Each signal's residuals are weighted by the design's noise floor (1 / sigma_s,
``criterion.prediction_floor``), not by the signal's spread as in a plain fit, so that fits and
comparison weigh the signals as the criterion did (the deflection is predicted to the
encoder's resolution, 2.2e-6 rad on the offset/asymmetry pair against a spread of ~1e-3 rad,
the motor angle to its start-velocity drift, 0.05 rad).

The rival with the lower held-out cost wins; the evidence is the realised log-likelihood ratio
over the held-out windows (the residuals in floor units are the Gaussian's: half the difference
of the rivals' sums of squares; what the design's criterion predicts), the relative cost
difference and
a one-sided Wilcoxon signed-rank test of the per-window differences (are the loser's held-out
windows consistently worse, not just a few). Differences, not the log ratios the diagnosis
ranks: in floor units each window's difference is its share of the log-likelihood ratio. The
decision is only called ``decisive`` when the test holds at ``max_p``; otherwise the winner is
the better fit, no more.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import wilcoxon

from ..identify.fit import FitResult, fit, window_costs
from ..identify.windows import Measured, Predictor, WindowDesign
from .rivals import Rival

MAX_P = 0.05


@dataclass
class Decision:
    winner: str
    loser: str
    cost_heldout: dict[str, float]
    relative_gap: float      # (loser - winner) / loser held-out cost
    p_value: float           # one-sided signed-rank test of per-window held-out differences
    fits: dict[str, FitResult]
    llr: float = 0.0         # realised log-likelihood ratio, winner over loser, held-out windows [nats]

    @property
    def decisive(self) -> bool:
        return self.p_value <= MAX_P

    def as_dict(self) -> dict:
        return {"winner": self.winner, "loser": self.loser, "decisive": self.decisive,
                "cost_heldout": self.cost_heldout, "relative_gap": self.relative_gap,
                "wilcoxon_p": self.p_value, "max_p": MAX_P, "log_likelihood_ratio_nats": self.llr,
                "fits": {k: v.as_dict() for k, v in self.fits.items()}}


def refit(predictor: Predictor, rival: Rival, max_iter: int, progress=None) -> FitResult:
    """``rival`` fitted to ``predictor``'s recording from its old fit, and from the effect's
    default values beside the old fit's shared ones, keeping the lower training cost. A
    recording that ties the rivals leaves the effect's own parameters anywhere along the tie
    (a play of 1e-7 rad, a hysteresis of 1e-6 rad, an input offset of the wrong sign traded
    against the Coulomb level), and from there the new recording's fit can end in a valley
    that names the other rival: a hysteresis truth's recording explained better by refitted
    backlash, an offset truth's by friction asymmetry at 10 times the offset's held-out cost."""
    first = fit(predictor, rival.structure, max_iter=max_iter, progress=progress)
    own = rival.drawn
    params = {p.name: p for p in rival.structure.params}
    start = rival.structure.with_values({n: params[n].initial for n in own})
    if np.array_equal(start.vector(own), rival.structure.vector(own)):
        return first
    second = fit(predictor, start, max_iter=max_iter, progress=progress)
    return min((first, second), key=lambda r: r.cost_train)


def decide(rivals: tuple[Rival, Rival], recording, floor: dict[str, float], window: WindowDesign = WindowDesign(),
           max_iter: int = 15, progress=None) -> Decision:
    """Fit both ``rivals`` to ``recording`` (a ``Recording``) with each predicted signal's
    residuals in units of ``floor`` (q, delta, tau), and name the rival it supports."""
    gear = rivals[0].structure.gear_ratio
    predictor = Predictor(Measured.from_recording(recording, gear), window)
    missing = [s for s in predictor.signals if s not in floor]
    if missing:
        raise ValueError(f"no noise floor for {', '.join(missing)} (have {', '.join(floor)})")
    predictor.scale = {s: float(floor[s]) for s in predictor.signals}
    fits, costs = {}, {}
    for r in rivals:
        fits[r.effect] = refit(predictor, r, max_iter, progress)
        costs[r.effect] = window_costs(predictor, fits[r.effect].structure, predictor.test)
    a, b = (r.effect for r in rivals)
    winner, loser = (a, b) if costs[a].mean() <= costs[b].mean() else (b, a)
    diff = costs[loser] - costs[winner]
    p = float(wilcoxon(diff, alternative="greater").pvalue) if np.any(diff != 0) else 1.0
    held = {k: float(v.mean()) for k, v in costs.items()}
    gap = (held[loser] - held[winner]) / held[loser] if held[loser] > 0 else 0.0
    # window_costs are mean squares over each window's scored samples (signals x cost columns).
    per_window = len(predictor.signals) * len(predictor.cols)
    return Decision(winner, loser, held, float(gap), p, fits, float(0.5 * per_window * diff.sum()))
