"""``mjjoint diagnose``: which physical effect does the model leave out of this recording?

Runs the fit -> locate -> name -> refit loop (``diagnosis.loop``) from a starting model and
reports where simulation and recording differ, the effects found missing in order, the
fitted model with them, the held-out NRMSE before and after, and whether the final model
explains the recording to its noise floor (``diagnosis.floor``).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..diagnosis.loop import DiagnoseOptions
from ..fleet.inputs import is_fleet
from ..identify.effects import EFFECTS
from .errors import CliError
from .fleet import add_fleet_options, check_single, run_fleet
from .options import Problem, add_problem_options, effect_names, prepare, run_info

DEFAULT_OUT = Path("out/diagnose")
OPTIONS = DiagnoseOptions()

EPILOG = f"""\
examples:
  mjjoint diagnose rec.csv --gear-ratio 160 --base coulomb_friction,viscous_friction,linear_stiffness
  mjjoint diagnose rec.csv --model my_joint.toml --max-rounds 2 --out out/run1
  mjjoint diagnose rec.csv --gear-ratio 160 --candidates backlash,input_delay,torque_ripple
  mjjoint diagnose DATA_EMPS.mat --plant linear --columns t=t,u=vir,q=qm,theta=qm --scales u=35.15
  mjjoint diagnose arm.csv --model arm.toml --joint 1,2   each joint of a multi-joint recording
  mjjoint diagnose arm.csv --arm arm.toml --joint 2       joint 2 loaded by the other joints' measured motion
  mjjoint diagnose friction_log.csv --friction-map          friction torque vs motion (t,q,tau)
  mjjoint diagnose logs/ --gear-ratio 160 --workers 4 --out fleet   every recording in a folder
  mjjoint diagnose 'logs/*/run*.mat' --columns t=t,u=cur,q=qm,theta=ql --out fleet   a quoted glob
  mjjoint diagnose robots.toml --scheduler tcp://head:8786 --out /shared/fleet   a manifest on a Dask cluster

writes DIR/index.html (verdict, per-step evidence, figures), diagnosis.json (same inputs and
seed give the same bytes), model.toml (the final model, for simulate --model), traces.rrd
(measured, before and after; 'rerun traces.rrd'),
PNGs and run.json (wall time); DIR appears only when complete. A multi-joint recording
(u1,q1,theta1,tau1,u2,...) is diagnosed joint by joint into DIR/joint{{j}}/; DIR/diagnosis.json
says which joints miss something ("mismatch_in") and DIR/index.html links the reports.
A folder, glob or manifest of recordings (docs/fleet.md) is diagnosed recording by recording
into DIR/<name>/; DIR/fleet.csv has a row per recording and joint, DIR/index.html links them,
and a rerun keeps the reports whose inputs are unchanged (--force redoes them).

candidate effects: {", ".join(EFFECTS)}
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "diagnose", help="name the physics a model lacks for a recording, with evidence",
        description="Fit the starting model to the recording, locate where its predictions miss, name the\n"
                    "missing effect that best explains held-out data, add it, refit; repeat until no candidate\n"
                    "passes, then judge the final model against the recording's noise floor.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_problem_options(p, DEFAULT_OUT)
    d = p.add_argument_group("diagnosis")
    d.add_argument("--max-rounds", type=int, default=OPTIONS.max_rounds, metavar="K",
                   help=f"most effects to add (default {OPTIONS.max_rounds})")
    d.add_argument("--min-gain", type=float, default=OPTIONS.min_gain, metavar="G",
                   help=f"relative held-out cost reduction needed to name an effect (default {OPTIONS.min_gain:g})")
    d.add_argument("--candidates", metavar="LIST", help="comma list of effects to consider (default: all)")
    d.add_argument("--fit-iter", type=int, default=OPTIONS.fit_iter, metavar="K",
                   help=f"LM iterations of each full fit (default {OPTIONS.fit_iter})")
    d.add_argument("--screen-iter", type=int, default=OPTIONS.screen_iter, metavar="K",
                   help=f"LM iterations when screening a candidate (default {OPTIONS.screen_iter})")
    d.add_argument("--friction-map", action="store_true",
                   help="REC is a friction log (t, q, tau: friction torque against a prescribed motion): "
                        "fit the friction effects to tau along the measured motion, no inertia; "
                        "reports friction RMS [N m] before and after")
    add_fleet_options(p)
    p.set_defaults(handler=run)


def options_from_args(args: argparse.Namespace) -> DiagnoseOptions:
    for flag, value in (("--max-rounds", args.max_rounds), ("--fit-iter", args.fit_iter),
                        ("--screen-iter", args.screen_iter)):
        if value < 1:
            raise CliError(f"{flag} {value} must be at least 1")
    if not 0 < args.min_gain < 1:
        raise CliError(f"--min-gain {args.min_gain:g} must lie in (0, 1)")
    candidates = None if args.candidates is None else tuple(effect_names(args.candidates, "--candidates"))
    return DiagnoseOptions(min_gain=args.min_gain, max_rounds=args.max_rounds, screen_iter=args.screen_iter,
                           fit_iter=args.fit_iter, candidates=candidates)


def run(args: argparse.Namespace) -> int:
    from ..report.progress import StepLog

    options = options_from_args(args)
    if args.friction_map:
        from .friction_map import run as friction_map
        return friction_map(args, options.candidates)
    if len(args.recording) == 1 and is_fleet(args.recording[0]):
        return run_fleet(args, args.recording[0])  # options checked above; each task rebuilds its own
    check_single(args)
    out, problem = prepare(args)
    if not isinstance(problem, Problem):
        from .per_joint import diagnose_joints
        return diagnose_joints(args, out, problem, options)
    data, seconds = diagnose_recording(args, out, problem, options, StepLog())
    from ..report.summary import diagnosis_summary
    print(diagnosis_summary(data, seconds))
    print(f"report: {out.path / 'index.html'}  (data: diagnosis.json, traces.rrd)")
    return 0


def diagnose_recording(args: argparse.Namespace, out, problem: Problem, options: DiagnoseOptions,
                       progress) -> tuple[dict, float]:
    """Diagnose one single-joint problem into ``out``; returns the diagnosis.json data and wall time."""
    from ..diagnosis.loop import diagnose
    from ..report.build import write_diagnosis

    start = time.perf_counter()
    diag = diagnose(problem.predictor, problem.base, options, progress=progress)
    seconds = time.perf_counter() - start
    run = {**run_info("diagnose", args, problem), "seconds": round(seconds, 3),
           "rollouts_full_length": round(diag.rollouts, 1)}
    with out.staged() as folder:
        data = write_diagnosis(folder, problem.predictor, diag, problem.source, run)
    return data, seconds
