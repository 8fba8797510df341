"""How much of the TRUE model's cost on the concealed dynamic_friction cases comes from windows
whose start state the recording does not determine.

A window that starts at rest takes its 2SEP states from a lead-in: the model simulated under the
measured input from the last sample where the motor moved (``Predictor._start_states``). Where
that lead-in starts is a choice; here each resting window is predicted by the truth from lead-ins
started at the last sample faster than f x ``Measured.moving_speed``, f in ``--factors``, and a
window whose cost spreads more than ``--spread`` times between them is "undetermined". Printed per
seed: the truth's training cost, with and without the undetermined windows, against the windows
that start moving (no lead-in); the same windows told without the truth, by how far a model's
own predictions from those lead-ins spread (their mean squared normalised difference, in noise
floors), for the truth and for the screen's start (the base with 2SEP at the catalogue's
values); with ``--fit``, the least-squares fit of every parameter from the truth, which leaves
out the windows the model being fitted leaves undetermined (``Predictor.undetermined``; the lag
gain B, the pre-sliding stiffness k, the costs; a few minutes per seed on 2 cores).

    python scripts/lead_in_spread.py                     # seeds 0-4, about 30 s on 2 cores
    python scripts/lead_in_spread.py --seeds 1 2 --fit
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from mjjoint.benchmark.cases import GEAR_RATIO, NOMINAL, make_case
from mjjoint.benchmark.score import write_case_recording
from mjjoint.identify.fit import fit, window_costs
from mjjoint.identify.structure import Structure
from mjjoint.identify.windows import LEAD_FACTORS, Measured, Predictor, WindowDesign
from mjjoint.recordings import read_recording


def predictor(measured: Measured, seed: int, factor: float = 1.0) -> Predictor:
    """The benchmark's predictor with resting windows' lead-ins from the last sample faster than
    ``factor`` x moving_speed (the same windows rest: those slower than moving_speed at their
    start)."""
    return Predictor(measured, WindowDesign(seed=seed)).with_lead(factor)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--factors", type=float, nargs="+", default=list(LEAD_FACTORS))
    ap.add_argument("--spread", type=float, default=2.0)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--fit", action="store_true", help="also fit the truth (the fit leaves out the windows it leaves undetermined)")
    args = ap.parse_args()
    for seed in args.seeds:
        case = make_case("dynamic_friction", seed)
        with tempfile.TemporaryDirectory() as tmp:
            path = write_case_recording(case, Path(tmp), args.duration)
            measured = Measured.from_recording(read_recording(path, gear_ratio=GEAR_RATIO), GEAR_RATIO)
        shifted = [predictor(measured, seed, f) for f in args.factors]
        costs = np.array([window_costs(p, case.truth, np.arange(len(p.starts))) for p in shifted])
        first = shifted[0]
        train = np.zeros(len(first.starts), bool)
        train[first.train] = True
        resting = first.resting & (first.lead_samples > 0)
        undetermined = resting & (costs.max(axis=0) > args.spread * np.maximum(costs.min(axis=0), 1e-300))
        c = costs[0]
        print(f"seed {seed}: B {case.truth.values['dynamic_friction.b']:.2f}, k {case.truth.values['dynamic_friction.k']:.0f}; "
              f"{int(resting[train].sum())} of {int(train.sum())} training windows rest, {int((undetermined & train).sum())} "
              f"undetermined ({np.flatnonzero(undetermined & train).tolist()}) holding {c[train & undetermined].sum() / c[train].sum():.0%} "
              f"of the truth's training cost {c[train].mean():.3g}; without them {c[train & ~undetermined].mean():.3g}; "
              f"windows that start moving {c[train & ~resting].mean():.3g}", flush=True)
        rest = np.flatnonzero(resting)
        start = Structure.create(case.base_effects, NOMINAL, GEAR_RATIO).with_effect("dynamic_friction")
        for label, structure in (("the truth", case.truth), ("the screen's start", start)):
            spread = first.lead_in_spread(structure, rest, args.factors)
            order = np.argsort(-spread)[:6]
            print(f"  predictions of {label} from those lead-ins spread by (noise floors): "
                  + ", ".join(f"window {rest[i]} {spread[i]:.3g}" for i in order), flush=True)
        if args.fit:
            r = fit(first, case.truth, max_iter=30)
            v = r.structure.values
            print(f"  fitted from the truth (leaving out the windows the fitted model leaves undetermined, "
                  f"{list(r.left_out)}): B {v['dynamic_friction.b']:.1f}, k {v['dynamic_friction.k']:.0f}, "
                  f"training cost {r.cost_train:.3g}, held-out {r.cost_test:.3g}", flush=True)


if __name__ == "__main__":
    main()
