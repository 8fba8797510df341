"""Run the diagnosis blind on an out-of-regime case and score its answer (docs/benchmark.md).

A case passes when
* the right effect is named (one of ``OutsideCase.right``, or a rival reported indistinguishable
  from it), or the verdict honestly says the model does not explain the recording and where
  (``explained`` false, with the located conditions or windows), or, for a control, nothing is
  named;
* nothing else is named (``tolerated`` names aside);
* ``explained`` is not true while a signal's final held-out NRMSE is more than ``FAR`` times
  the floor the TRUE sensors set (their known noise over the signal's spread, at least the
  floor's resolution): the scorer's floor, not the tool's own estimate of it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from .cases import OutsideCase, make_case
from .record import Excitation, record, write_csv

FAR = 3.0            # final NRMSE this multiple of the true floor: "far above" it
RESOLUTION = 0.01    # no NRMSE below this counts as a floor (integration differences)


@dataclass
class OutsideScore:
    case: str
    seed: int
    named: list[str]
    right: bool                 # a right effect named
    honest: bool                # not explained, and the verdict locates the mismatch
    false_additions: list[str]
    explained: bool
    explained_above_floor: bool
    worst: str                  # the signal furthest above the true floor
    nrmse_before: float
    nrmse_after: float
    true_floor: float
    verdict: str
    seconds: float
    stand_ins: list[str] = field(default_factory=list)
    tool_floor: float = 0.0     # the tool's own floor of the worst signal (its twin's windowing included)

    @property
    def passed(self) -> bool:
        answered = self.right or self.honest or (not self.named and self.explained)
        return answered and not self.false_additions and not self.explained_above_floor


def located(verdict: str) -> bool:
    """Whether a not-explained verdict says where the mismatch is (signal, conditions or time)."""
    return "against a floor of" in verdict and ("concentrates" in verdict or "largest at" in verdict)


def score_diagnosis(case: OutsideCase, diag, seconds: float) -> OutsideScore:
    floor = diag.floor.as_dict()
    noise = case.true_noise()
    # The true measurement floor as NRMSE: the known noise over the tool's own normalisation
    # (its measurement NRMSE is its estimated noise over that spread).
    true_floor = {s: max(RESOLUTION, floor["measurement_nrmse"][s] * noise[s] / floor["noise_std"][s])
                  for s in floor["measurement_nrmse"] if floor["noise_std"][s] > 0}
    after = diag.final.nrmse_test
    ratio = {s: after[s] / f for s, f in true_floor.items()}
    worst = max(ratio, key=ratio.get)
    found = set()
    for st in diag.steps:
        if st.effect in case.right or set(st.alternatives) & set(case.right):
            found.add(st.effect)
    false = [e for e in diag.missing if e not in found and e not in case.right and e not in case.tolerated]
    return OutsideScore(case.name, case.seed, list(diag.missing), bool(found),
                        (not diag.explained) and located(diag.verdict), false, bool(diag.explained),
                        bool(diag.explained) and ratio[worst] > FAR, worst, diag.initial.nrmse_test[worst],
                        after[worst], true_floor[worst], diag.verdict, seconds, list(diag.stand_ins),
                        float(floor["nrmse"][worst]))


def run_case(name: str, seed: int, folder: Path, duration: float = 6.0, progress=None, options=None,
             torque: bool = True, rate: float = Excitation.rate, program: str = Excitation.program) -> OutsideScore:
    """Record the case at ``rate`` [Hz] under the excitation ``program``, write its CSV (without the torque column where ``torque``
    is false: a joint with no torque sensor, as most robots are), diagnose the CSV as a user would
    (``options``: a ``DiagnoseOptions``, default the command line's), and score it."""
    from ... import diagnose  # the public API, as ``mjjoint diagnose`` runs it
    case = make_case(name, seed, duration, rate, program)
    cols = record(case.plant, case.excitation, case.sensors, seed)
    path = write_csv(folder / "recording.csv", {k: v for k, v in cols.items() if torque or k != "tau"})
    start = time.perf_counter()
    diag = diagnose(path, gear_ratio=case.plant.gear_ratio, base=list(case.base), progress=progress, options=options)
    return score_diagnosis(case, diag, time.perf_counter() - start)
