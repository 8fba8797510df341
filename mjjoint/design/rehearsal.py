"""The decision rehearsed on simulated recordings of a candidate input, each rival in turn the truth.

The criterion D (``criterion``) linearises the wrong rival's refit about its old fit; the
parameters that absorb a difference can move far (a play width from nothing to millimetres,
an offset to zero), and there the linearisation promises separation the refit then removes
(docs/design-experiments.md: 5.8e9 nats promised, the refitted rivals tied). So the best few
inputs by D are rehearsed: each rival's run of the input, logged by the lab's sensors (fresh
noise), is decided exactly as the new recording will be (``decide.decide``: both rivals
refitted, compared on the held-out windows), and the realised log-likelihood ratio towards
the rival that made the recording is the evidence. The rehearsed score is the smaller of the
two (either rival may be the truth); negative where a rehearsal named the wrong rival.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

from ..identify.windows import WindowDesign
from ..rehearse.sensors import Sensors
from .decide import decide
from .record import logged

# Noise seeds of the rehearsed recordings: apart from the floor's (``criterion.input_floor``).
SEED = 1000


@dataclass(frozen=True)
class Rehearsal:
    """Per rival as the truth: the realised log-likelihood ratio towards it [nats] (negative:
    the decision named the other) and the signed-rank p of that decision."""

    evidence: tuple[float, float]
    p_values: tuple[float, float]

    @property
    def score(self) -> float:
        return min(self.evidence)

    def as_dict(self) -> dict:
        return {"evidence_nats": list(self.evidence), "wilcoxon_p": list(self.p_values), "score_nats": self.score}


def rehearse(rivals, traces, floor: dict[str, float], window: WindowDesign = WindowDesign(),
             max_iter: int = 8, sensors: Sensors = Sensors(seed=SEED)) -> Rehearsal:
    """Decide on each rival's run ``traces[k]`` of the input, logged with ``sensors``."""
    evidence, p_values = [], []
    for k, (rival, tr) in enumerate(zip(rivals, traces)):
        rec = logged(tr, replace(sensors, seed=sensors.seed + k))
        d = decide(tuple(rivals), rec, floor, window, max_iter=max_iter)
        evidence.append(d.llr if d.winner == rival.effect else -d.llr)
        p_values.append(d.p_value)
    return Rehearsal(tuple(evidence), tuple(p_values))
