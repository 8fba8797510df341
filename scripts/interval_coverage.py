"""Coverage of the fits' 95 % intervals, per effect, over simulated recordings.

For each effect and seed: the case's truth (``benchmark.cases``: a concealed case's, or one drawn
for the coverage alone, ``COVERAGE_ONLY``) records the lab programme in closed loop; the TRUE
structure is fitted to it from the catalogue's initial values, as ``mjjoint fit`` fits
(``--restarts``, its default: staged, restarted where it ends on a bound); each parameter's 95 %
interval is checked against the truth (``benchmark.coverage``). Coverage is reported over the
fits where a parameter is identifiable; the rest are counted apart.

    python scripts/interval_coverage.py --seeds 6 --duration 10

prints one row per effect and per parameter of the case's effect, then the pooled coverage
of every parameter; docs/diagnosis.md ("Intervals") holds the table.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from mjjoint.benchmark.cases import TRUTHS
from mjjoint.benchmark.coverage import CHECKS, coverage_fit, covered
from mjjoint.cli.fit import RESTARTS
from mjjoint.identify.effects import EFFECTS

EFFECTS_SCORED = tuple(e for e in TRUTHS if e not in ("none", "gravity"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--fit-iter", type=int, default=30)
    ap.add_argument("--restarts", type=int, default=RESTARTS, help=f"as mjjoint fit's (default {RESTARTS})")
    ap.add_argument("--truth-step", type=float, default=None,
                    help="the truth's timestep [s] (default the fitted model's, 0.5 ms); a finer one records "
                         "physics nearer its converged solution, which no model's step matches exactly")
    ap.add_argument("--effects", default=",".join(EFFECTS_SCORED))
    ap.add_argument("--check", choices=CHECKS, default="own",
                    help="whose intervals are checked against the model (fit.check_intervals): the case's "
                         "effect's parameters (as the diagnosis checks the effects it names), every "
                         "parameter's, or none (the linearised intervals); with own or all, every interval is also "
                         "widened by its step bias and its twin bias, as the diagnosis and mjjoint fit widen them")
    args = ap.parse_args(argv)
    unknown = [e for e in args.effects.split(",") if e not in TRUTHS or e == "none"]
    if unknown:
        ap.error(f"--effects: {unknown[0]!r} is not a case with parameters "
                 f"(allowed: {', '.join(e for e in TRUTHS if e != 'none')})")
    pooled: dict[str, list[tuple[bool, bool]]] = {}
    print("effect                   parameter                         identifiable  covered")
    for effect in args.effects.split(","):
        own = [p.name for p in EFFECTS[effect].params]
        rows: dict[str, list[tuple[bool, bool]]] = {}
        for seed in range(args.seeds):
            case, result, explained, fitted = coverage_fit(effect, seed, args.duration, args.truth_step,
                                                           args.fit_iter, args.restarts, args.check)
            for name, c in covered(result, case.truth, explained).items():
                rows.setdefault(name, []).append(c)
                pooled.setdefault(name, []).append(c)
                if c == (False, True) and name not in own:
                    lo, hi = result.intervals[name]
                    print(f"    missed: {name}: truth {case.truth.values[name]:.4g}, estimate "
                          f"{result.structure.values[name]:.4g}, interval {lo:.4g} .. {hi:.4g}", file=sys.stderr)
            print(f"  {effect} seed {seed}: {'explained' if explained else 'NOT explained'}, held-out NRMSE "
                  + ", ".join(f"{s} {v:.3f}" for s, v in result.nrmse_test.items())
                  + f"; fit {fitted:.0f} rollouts, check {result.rollouts - fitted:.1f}", file=sys.stderr, flush=True)
            for name in own:
                lo, hi = result.intervals[name]
                print(f"    {name}: truth {case.truth.values[name]:.4g}, estimate {result.structure.values[name]:.4g}, "
                      f"interval {lo:.4g} .. {hi:.4g}",
                      *[f"({w})" for w in result.warnings if w.startswith(f"{name} ")], file=sys.stderr, flush=True)
        for name in own:
            ident = [c for c, i in rows.get(name, []) if i]
            share = f"{100 * np.mean(ident):5.0f} %" if ident else "    -"
            print(f"{effect:24s} {name:33s} {len(ident):3d} of {len(rows.get(name, [])):3d}  {share}", flush=True)
    ident = [c for cs in pooled.values() for c, i in cs if i]
    print(f"{'all parameters, all fits':58s} {len(ident):3d} of {sum(map(len, pooled.values())):3d}  "
          f"{100 * np.mean(ident):5.0f} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
