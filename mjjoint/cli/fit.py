"""``mjjoint fit``: fit a model structure's parameters to a recording, with 95 % intervals.

The options it shares with ``diagnose`` are in ``options``. A multi-joint recording goes to
``per_joint``, which runs the same on each joint.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..identify.effects import EFFECTS
from .errors import CliError
from .options import Problem, add_problem_options, prepare, run_info

DEFAULT_OUT = Path("out/fit")
RESTARTS = 2  # fit --restarts default (mjjoint.fit's too)

EPILOG = """\
examples:
  mjjoint fit rec.csv --gear-ratio 160                         the seed paper's full joint
  mjjoint fit rec.csv --gear-ratio 160 --base linear_stiffness,coulomb_friction --out out/fit1
  mjjoint fit rec.mat --gear-ratio 100 --columns t=time,u=cur,q=qm,theta=ql --scales q=deg,theta=deg --k-m 0.25
  mjjoint fit rec.csv --model examples/stiff_linear.yaml --max-iter 40
  mjjoint fit DATA_EMPS.mat --plant linear --columns t=t,u=vir,q=qm,theta=qm --scales u=35.15 \
      --base coulomb_friction,viscous_friction,input_offset
  mjjoint fit arm.csv --gear-ratio 160,100 --joint 2            joint 2 of a multi-joint recording (u1,q1,...)

writes DIR/fit.json (parameters, 95 % intervals, warnings, NRMSE), model.toml (the fitted model,
for simulate --model), heldout_windows.png, residual.png, traces.rrd, index.html and run.json;
DIR appears only when complete. Several recordings (REC1 REC2 ...) are fitted together as
separate segments: no window spans two.

A multi-joint recording (columns u1,q1,theta1,tau1,u2,...) is fitted joint by joint: DIR/joint{j}/
holds each joint's files, DIR/fit.json and DIR/index.html gather them (docs/multijoint.md).

effects (--base): minimal, """ + ", ".join(EFFECTS)


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "fit", help="fit a model's parameters to a recording (95 %% intervals, held-out NRMSE)",
        description="Fit the parameters of a model structure to a recording by windowed k-step-ahead\n"
                    "prediction error, and report them with 95 % intervals and identifiability warnings.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_problem_options(p, DEFAULT_OUT)
    p.add_argument("--max-iter", type=int, default=25, metavar="K", help="Levenberg-Marquardt iterations (default 25)")
    p.add_argument("--restarts", type=int, default=RESTARTS, metavar="K",
                   help="starting points tried when the fit ends on a bound or far above the noise floor: "
                        f"the recording's initial values, then seeded random ones (default {RESTARTS}; 0: none, "
                        "and no staged fit: the effects that refine another held while the rest are fitted)")
    p.set_defaults(handler=run)


def fitted(problem: Problem, args: argparse.Namespace, progress):
    """(the fit of ``problem``'s starting model as reported, ``identify.fit.reported``, its noise
    floor)."""
    from ..diagnosis.floor import judged
    from ..identify.fit import fit, reported
    from ..identify.twin import Twin
    result = fit(problem.predictor, problem.base, max_iter=args.max_iter, progress=progress, restarts=args.restarts)
    twin = Twin(problem.predictor, result.structure)  # one free run for the intervals' bias and the floor
    result, floor, _ = judged(problem.predictor, reported(problem.predictor, result, twin), twin)
    return result, floor


def run(args: argparse.Namespace) -> int:
    from ..report.progress import FitProgress

    if args.max_iter < 1:
        raise CliError(f"--max-iter {args.max_iter} must be at least 1")
    if args.restarts < 0:
        raise CliError(f"--restarts {args.restarts} must be at least 0")
    out, problem = prepare(args)
    if not isinstance(problem, Problem):
        from .per_joint import fit_joints
        return fit_joints(args, out, problem)
    start = time.perf_counter()
    with FitProgress(args.max_iter) as progress:
        result, floor = fitted(problem, args, progress)
    seconds = time.perf_counter() - start

    from ..report.build import write_fit
    from ..report.summary import judged_lines, parameter_table
    run = {**run_info("fit", args, problem), "seconds": round(seconds, 3),
           "rollouts_full_length": round(result.rollouts, 1)}
    with out.staged() as folder:
        data = write_fit(folder, problem.predictor, result, problem.base, problem.source, run, floor)
    st = result.structure
    print(f"fitted {', '.join(st.effects) or 'the minimal model'} to {problem.source} "
          f"({result.iterations} iterations, {result.rollouts:.0f} full-length rollouts, {seconds:.1f} s, "
          f"best of {result.starts} start{'s' if result.starts > 1 else ''})")
    print(parameter_table(st.values, result.intervals, result.warnings, st.describe()["units"]))
    print("held-out NRMSE per signal (noise floor: the recording's noise and the fitted model's simulated twin, "
          "counted up to twice it):")
    print("\n".join(judged_lines(data, result.nrmse_test)))
    if not data["explained"]:
        print("the model misses the recording above the noise: `mjjoint diagnose` looks for what it lacks")
    print(f"wrote {out.path}/ (fit.json, index.html, traces.rrd, PNGs)")
    return 0
