"""Does the designed experiment separate rivals that tied? (``mjjoint design``, issue 24)

For each rival pair of ``mjjoint.benchmark.design_cases`` and truths drawn on either side of it
(seeds), the truth's original recording (a programme under which the two explanations tie) is
fitted with both rivals, the experiment is designed within the limits below, recorded from the
truth (lab sensors, fresh noise) and decided. Reported per case: the original held-out costs
of both rivals (the tie), the family chosen, D and the default chirp's D (the chirp at the
largest amplitude within the limits, if any), the largest share of a limit the truth's run
uses, the discrimination predicted for the held-out windows (D scaled to them, and the
rehearsed decisions' smaller log-likelihood ratio) against the realised one, the winner and its
signed-rank p. Summary per pair: share named correctly (over the draws whose original recording
tied: costs within TIE), share where the design beats the chirp, limits ever exceeded.

    python scripts/bench_design.py                          # 3 pairs x 2 sides x 3 seeds
    python scripts/bench_design.py --pairs offset_asymmetry --seeds 5 --json out.json
    python scripts/bench_design.py --loop                   # references for a PD on the motor
    python scripts/bench_design.py --loop --tied-only       # design only the draws that tied
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time

import numpy as np

from mjjoint.benchmark.design_cases import PAIRS, fit_rivals, make_design_case, run_case, tie
from mjjoint.design import Limits, SearchOptions
from mjjoint.rehearse import Controller

LIMITS = Limits(max_torque=0.2, max_speed=80.0, angle_range=1.0, duration=8.0)
TIE = 0.05  # a draw counts where the worse rival's original held-out cost is within 5 % of the better's


def calibration(results: list[dict]) -> None:
    """How far each prediction of the decision's log-likelihood ratio is from the realised one,
    over the designed draws named correctly (the realised ratio then positive): the median ratio
    predicted / realised, its range, and the share within a factor of 10 either way; and over
    every designed draw, how often the realised ratio reached the prediction (the prediction a
    lower figure there)."""
    ok = [r for r in results if r.get("correct") and r.get("rehearsed") is not None and r["llr"] > 0]
    designed = [r for r in results if r.get("family") is not None and r.get("rehearsed") is not None]
    for name, key in (("D held-out", "D_heldout"), ("rehearsed (truth's side)", "rehearsed_truth_side"),
                      ("rehearsed (min)", "rehearsed")):
        ratios = np.array([r[key] / r["llr"] for r in ok])
        pos = ratios[ratios > 0]
        covered = sum(r["llr"] >= r[key] for r in designed)
        print(f"calibration, {name}: the realised ratio at least this in {covered}/{len(designed)} designed draws",
              end="")
        if not len(pos):
            print()
            continue
        within = np.mean((pos >= 0.1) & (pos <= 10.0)) * len(pos) / len(ratios)
        print(f"; / realised over {len(ratios)} correct draws: median {np.median(pos):.3g} "
              f"({pos.min():.2g} to {pos.max():.2g}; {len(ratios) - len(pos)} not positive), "
              f"within a factor 10 in {within:.0%}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", default=",".join(PAIRS), help="comma list of pairs")
    ap.add_argument("--seeds", type=int, default=3, help="truths per side of each pair")
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--starts", type=int, default=4, help="Sobol points per family")
    ap.add_argument("--refine", type=int, default=6, help="Nelder-Mead evaluations")
    ap.add_argument("--draws", type=int, default=2, help="parameter draws per rival")
    ap.add_argument("--max-iter", type=int, default=10, help="LM iterations per fit")
    ap.add_argument("--push", type=int, default=SearchOptions().push,
                    help="evaluations spent searching on from the chirp where nothing beats it")
    ap.add_argument("--rehearse", type=int, default=2, help="best inputs whose decision is rehearsed")
    ap.add_argument("--loop", action="store_true", help="closed loop: design references for a PD on the motor")
    ap.add_argument("--duration", type=float, default=LIMITS.duration, help="original and designed record [s]")
    ap.add_argument("--tied-only", action="store_true",
                    help="design only the draws whose original recording tied (the others: one line, no design)")
    ap.add_argument("--json", help="write every case's result here")
    ap.add_argument("--calibration", metavar="JSON", help="only print the calibration of the results in JSON "
                    "(a --json file of an earlier run)")
    args = ap.parse_args()
    if args.calibration:
        with open(args.calibration, encoding="utf-8") as f:
            calibration(json.load(f))
        return
    options = SearchOptions(starts=args.starts, refine=args.refine, draws=args.draws, rehearse=args.rehearse,
                            push=args.push)
    loop = Controller() if args.loop else None
    limits = dataclasses.replace(LIMITS, duration=args.duration)
    print(f"limits: {limits}; search: {options}; loop: {loop}; load average {os.getloadavg()[0]:.1f}")
    header = ("pair", "truth", "seed", "tie", "family", "D", "D chirp", "truth usage", "D held-out",
              "rehearsed (min)", "rehearsed (truth's side)", "realised", "winner", "p")
    print("| " + " | ".join(header) + " |\n|" + "---|" * len(header))
    results = []
    start = time.perf_counter()
    for pair in args.pairs.split(","):
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            for side in (0, 1):
                case = make_design_case(pair, side, seed, args.duration)
                fitted = fit_rivals(case, args.max_iter)
                if args.tied_only and tie(fitted[1]) > TIE:
                    print(f"| {pair} | {case.truth_effect} | {seed} | {tie(fitted[1]):.1%} | (did not tie: "
                          f"not designed) | | | | | | | | | |", flush=True)
                    results.append({**fitted[1], "family": None, "untied": True, "correct": False})
                    continue
                r = run_case(case, limits, options, max_iter=args.max_iter, loop=loop, fitted=fitted)
                results.append(r)
                if r["family"] is None:
                    print(f"| {pair} | {r['truth']} | {seed} | {tie(r):.1%} | none within "
                          f"the limits | | | | | | | | (failed) | |", flush=True)
                    continue
                chirp = f"{r['D_chirp']:.3g}" + ("" if r["chirp_feasible"] else " (over limits)")
                rehearsed = "" if r["rehearsed"] is None else f"{r['rehearsed']:.3g} | {r['rehearsed_truth_side']:.3g}"
                print(f"| {pair} | {r['truth']} | {seed} | {tie(r):.1%} | {r['family']} | "
                      f"{r['D']:.3g} | {chirp} | "
                      f"{r['truth_usage']:.2f}{'' if not r['truth_violations'] else ' (NO)'} | "
                      f"{r['D_heldout']:.3g} | {rehearsed} | {r['llr']:.3g} | "
                      f"{r['winner']}{'' if r['correct'] else ' (wrong)'} | {r['p']:.2g} |", flush=True)
                if r["unbeaten"]:
                    print(f"(no better than the chirp: {r['unbeaten']})", flush=True)
    print(f"\n{time.perf_counter() - start:.0f} s in all")
    for pair in [*args.pairs.split(","), None]:
        drawn = [r for r in results if pair is None or r["pair"] == pair]
        every = [r for r in drawn if not r.get("untied")]   # the draws designed or tried
        rs = [r for r in every if tie(r) <= TIE]
        designed = [r for r in every if r["family"] is not None]
        feasible = [r for r in designed if r["chirp_feasible"]]
        sides = {e: f"{sum(r['correct'] for r in rs if r['truth'] == e)}/{sum(r['truth'] == e for r in rs)}"
                 for e in dict.fromkeys(r["truth"] for r in rs)}
        print(f"{pair or 'all pairs'}: of {len(rs)} tied draws ({len(drawn) - len(rs)} did not tie) named correctly "
              f"{sum(r['correct'] for r in rs)}/{len(rs)} (per truth {sides}), decisive "
              f"{sum(r['correct'] and r['decisive'] for r in rs)}/{len(rs)}; design beats the chirp "
              f"{sum(r['D'] > r['D_chirp'] for r in feasible)}/{len(feasible)} where the chirp fits the limits "
              f"({len(designed) - len(feasible)} where it cannot); no design within the limits "
              f"{len(every) - len(designed)}/{len(every)}; limits exceeded "
              f"{sum(r['usage'] > 1 or bool(r['truth_violations']) for r in designed)}/{len(designed)}; "
              f"all draws designed named correctly {sum(r['correct'] for r in every)}/{len(every)}")
    calibration(results)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
