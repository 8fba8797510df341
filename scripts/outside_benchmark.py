"""Out-of-regime benchmark: the diagnosis on recordings of an independently written plant.

Truths come from ``mjjoint.benchmark.independent`` (the seed's joint in numpy RK4, LuGre or
Maxwell-slip friction, effects outside the catalogue, other scales, a lumped flexible rod, two
effects at once), drawn per seed from ranges the development set does not use. Each recording
is written as CSV and diagnosed through ``mjjoint.diagnose`` with the base effect list, as a
user would. Scores per case (``independent/score.py``): right effect named or honestly
"unexplained" with its location, false additions, and ``explained`` never true far above the
true sensors' floor.

    python scripts/outside_benchmark.py                       # every case, seed 0, 6 s
    python scripts/outside_benchmark.py --cases control cogging --seeds 0 1
    python scripts/outside_benchmark.py --no-torque           # the same joints, no torque sensor
    python scripts/outside_benchmark.py --rate 250            # recorded (and controlled) at 250 Hz
    python scripts/outside_benchmark.py --program moves       # a robot's point-to-point moves
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from mjjoint.benchmark.independent.cases import CASES
from mjjoint.benchmark.independent.record import PROGRAMS, Excitation
from mjjoint.benchmark.independent.score import run_case


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--duration", type=float, default=6.0, help="recording length [s] (default 6)")
    ap.add_argument("--rate", type=float, default=Excitation.rate,
                    help=f"sample rate [Hz] of the recordings and of the PD loop (default {Excitation.rate:g})")
    ap.add_argument("--program", default=Excitation.program, choices=PROGRAMS,
                    help="the link reference: a slow sine, multisine and dwell (sweep, default) or a robot's "
                         "point-to-point moves (moves)")
    ap.add_argument("--out", type=Path, default=Path("out/outside"))
    ap.add_argument("--no-torque", action="store_true",
                    help="leave the torque column out of the recordings (a joint with no torque sensor)")
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    if not args.rate > 0:
        ap.error(f"--rate: {args.rate:g} Hz out of range (allowed: > 0)")
    rows, failed = [], []
    for seed in args.seeds:
        for name in args.cases:
            say = None if args.quiet else (lambda m, c=name: print(f"[{c}] {m}", flush=True))
            try:
                s = run_case(name, seed, args.out / f"{name}-{seed}", args.duration, progress=say,
                             torque=not args.no_torque, rate=args.rate, program=args.program)
            except FloatingPointError as e:
                print(f"[{name}] not recorded: {e}", flush=True)
                failed.append(f"{name}-{seed}")
                continue
            except ValueError as e:  # a recording the diagnosis refuses (too short for its windows)
                ap.error(f"[{name}] {e}")
            rows.append(s)
            print(f"[{name}] named={s.named} explained={s.explained} {s.worst} NRMSE {s.nrmse_before:.3f}->"
                  f"{s.nrmse_after:.3f} (true floor {s.true_floor:.3f}) {'PASS' if s.passed else 'FAIL'}\n"
                  f"[{name}] verdict: {s.verdict}", flush=True)
    print("\n| case | seed | hidden physics | named | right | honest | false additions | explained | "
          "worst signal: NRMSE before -> after (true floor; tool's floor) | s | pass |\n|" + "---|" * 11)
    for s in rows:
        print(f"| {s.case} | {s.seed} | {CASES[s.case][0]} | {', '.join(s.named) or '-'} | {'yes' if s.right else '-'} | "
              f"{'yes' if s.honest else '-'} | {', '.join(s.false_additions) or 'none'} | "
              f"{'**yes, above**' if s.explained_above_floor else ('yes' if s.explained else 'no')} | "
              f"{s.worst} {s.nrmse_before:.3f} -> {s.nrmse_after:.3f} ({s.true_floor:.3f}; {s.tool_floor:.3f}) | "
              f"{s.seconds:.0f} | "
              f"{'yes' if s.passed else '**no**'} |")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "summary.json").write_text(json.dumps([{**s.__dict__, "passed": s.passed} for s in rows], indent=1))
    print(f"\n{sum(s.passed for s in rows)}/{len(rows)} cases pass; summary in {args.out / 'summary.json'}"
          + (f"; not recorded: {', '.join(failed)}" if failed else ""))
    return 0 if all(s.passed for s in rows) and not failed else 1


if __name__ == "__main__":
    sys.exit(main())
