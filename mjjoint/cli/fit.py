"""``mjjoint fit``: fit a model structure's parameters to a recording, with 95 % intervals.

Also the shared input side of ``fit`` and ``diagnose``: reading the recording, the windowed
predictor, and the starting structure from ``--base`` (effect names) or ``--model`` (a model
file whose terms are mapped onto effect names, its values as initial values). A multi-joint
recording goes to ``per_joint``, which runs the same on each joint.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..assets import ArmSpec, DriveSpec
from ..assets.multi import read_model_file
from ..identify.initial import estimate
from ..identify.effects import EFFECTS, SEED_EFFECTS, check_effects, plant_effects
from ..identify.structure import Structure
from ..identify.windows import MAX_LEAD, Measured, Predictor, WindowDesign
from ..joint import JointParams
from ..modelfile import ModelFile
from ..physics.twosep import TwoSEP
from ..report.output import DESTINATION_RULE
from ..recordings import Recording, parse_column_map, parse_scales, read_recording
from ..recordings.resample import describe as describe_resampling
from .errors import CliError

DEFAULT_OUT = Path("out/fit")
PLANTS = {"arm": "", "linear": "slide", "rotary": "hinge"}  # --plant -> direct drive joint type
FIT_SIGNALS = {"q": "q", "theta": "delta", "tau": "tau"}  # --fit-signals name -> the cost's signal
MINIMAL = "minimal"
RESTARTS = 2  # fit --restarts default

EPILOG = """\
examples:
  mjjoint fit rec.csv --gear-ratio 160                         the seed paper's full joint
  mjjoint fit rec.csv --gear-ratio 160 --base linear_stiffness,coulomb_friction --out out/fit1
  mjjoint fit rec.mat --gear-ratio 100 --columns t=time,u=cur,q=qm,theta=ql --scales q=deg,theta=deg --k-m 0.25
  mjjoint fit rec.csv --model examples/stiff_linear.yaml --max-iter 40
  mjjoint fit DATA_EMPS.mat --plant linear --columns t=t,u=vir,q=qm,theta=qm --scales u=35.15 \
      --base coulomb_friction,viscous_friction,input_offset
  mjjoint fit arm.csv --gear-ratio 160,100 --joint 2            joint 2 of a multi-joint recording (u1,q1,...)

writes DIR/fit.json (parameters, 95 % intervals, warnings, NRMSE), heldout_windows.png,
residual.png, traces.rrd, index.html and run.json; DIR appears only when complete.

A multi-joint recording (columns u1,q1,theta1,tau1,u2,...) is fitted joint by joint: DIR/joint{j}/
holds each joint's files, DIR/fit.json and DIR/index.html gather them (docs/multijoint.md).

effects (--base): minimal, """ + ", ".join(EFFECTS)


def numbers(text: str) -> float | tuple[float, ...]:
    """A number, or a comma list of numbers: one per joint of a multi-joint recording."""
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or a comma list of numbers") from None
    return values[0] if len(values) == 1 else values


def joint_numbers(text: str) -> tuple[int, ...]:
    """Joint numbers J[,K...] (from 1, as the column suffixes), in increasing order."""
    try:
        joints = sorted({int(x) for x in text.split(",")})
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a joint number or a comma list of them") from None
    if joints[0] < 1:
        raise argparse.ArgumentTypeError(f"joints are numbered from 1, got {joints[0]}")
    return tuple(joints)


def add_problem_options(p: argparse.ArgumentParser, default_out: Path) -> None:
    """Options shared by fit and diagnose: the recording, the starting model, windows, output."""
    p.add_argument("recording", type=Path, metavar="REC",
                   help="recording: .csv (t,u,q,theta[,tau]; several joints: t,u1,q1,theta1,...), .npz or .mat")
    r = p.add_argument_group("recording")
    r.add_argument("--gear-ratio", type=numbers, metavar="N",
                   help="gear ratio (required unless --model gives it); N1,N2,... one per joint")
    r.add_argument("--columns", metavar="MAP", help="file names of the signals, e.g. t=time,u=cur,q=qm,theta=ql")
    r.add_argument("--scales", metavar="MAP", help="factors to SI, e.g. q=deg,theta=deg,u=2.5")
    r.add_argument("--allow-gaps", action="store_true",
                   help="interpolate across time steps longer than 5 median periods instead of refusing")
    r.add_argument("--k-m", type=numbers, metavar="K",
                   help="torque constant [N m/A]: u is recorded as a current; K1,K2,... one per joint")
    r.add_argument("--joint", type=joint_numbers, metavar="J[,K]",
                   help="joints of a multi-joint recording to work on (default: all)")
    m = p.add_argument_group("starting model (default: the seed paper's full joint)")
    x = m.add_mutually_exclusive_group()
    x.add_argument("--model", type=Path, metavar="FILE",
                   help="model file (.toml/.yaml): its terms become effects, its values initial values; "
                        "a [[joint]] file gives each joint of a multi-joint recording its own")
    x.add_argument("--base", metavar="LIST", help="comma list of effect names ('minimal': none)")
    m.add_argument("--plant", choices=PLANTS, default="arm",
                   help="arm: the elastic joint (q and theta measured); linear or rotary: a direct drive, "
                        "one joint and no gear, only q used (map theta to q's column, e.g. theta=qm); "
                        "default arm")
    w = p.add_argument_group("prediction windows")
    w.add_argument("--window-length", type=float, default=WindowDesign.length, metavar="S",
                   help=f"prediction horizon of each window (default {WindowDesign.length:g} s)")
    w.add_argument("--lead-in", type=float, default=WindowDesign.lead, metavar="S",
                   help="longest simulated lead-in of a window that starts at rest, for 2SEP's "
                        f"states (default {WindowDesign.lead:g} s; 0: none)")
    w.add_argument("--seed", type=int, default=0, metavar="S", help="which windows are held out (default 0)")
    w.add_argument("--fit-signals", metavar="LIST",
                   help="signals the cost scores, a comma list among q, theta (as the deflection q/N - theta), "
                        "tau (default: every one recorded)")
    p.add_argument("--out", type=Path, default=default_out, metavar="DIR",
                   help=f"output folder (default {default_out}; {DESTINATION_RULE})")


def effect_names(text: str, option: str, known: tuple[str, ...] = tuple(EFFECTS)) -> list[str]:
    """Names of a comma list, each one of ``known``; one line naming the known ones otherwise."""
    names = list(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    unknown = [n for n in names if n not in known]
    if not names or unknown:
        what = f"unknown effect {unknown[0]!r}" if unknown else "no effect named"
        raise CliError(f"{option}: {what} (known: {', '.join(known)})")
    return names


def effect_list(text: str, option: str = "--base", known: tuple[str, ...] = tuple(EFFECTS)) -> tuple[str, ...]:
    """The effects of a starting structure ('minimal' alone: none), prerequisites checked."""
    names = effect_names(text, option, (MINIMAL, *known))
    if names == [MINIMAL]:
        return ()
    if MINIMAL in names:
        raise CliError(f"{option}: '{MINIMAL}' means no effect; do not list it with others")
    try:
        return check_effects(names, known)
    except ValueError as exc:
        raise CliError(f"{option}: {exc}") from None


def structure_from_model(model: ModelFile, gear_ratio: float | None) -> tuple[Structure, list[str]]:
    """The structure a model file describes, and notes on what the effect catalogue cannot hold.

    Every switched-on term becomes its effect with the file's values as initial values; the
    arm is the nominal ArmSpec (inertias, masses, timestep).
    """
    if model.arm is None or model.joint is None:
        raise CliError("--model: an MJCF (.xml) model cannot be mapped onto effects; "
                       "give a .toml/.yaml model file or --base")
    arm, joint = model.arm, model.joint
    if (joint.motor_joint, joint.link_joint) != (JointParams.motor_joint, JointParams.link_joint):
        raise CliError("--model: the joint fixes a side to the world; fit and diagnose need the free arm")
    tr = joint.transmission
    if gear_ratio is not None and gear_ratio != tr.gear_ratio:
        raise CliError(f"--gear-ratio {gear_ratio:g} differs from the model file's "
                       f"transmission.gear_ratio {tr.gear_ratio:g}")
    values: dict[str, float] = {"linear_stiffness.k1": tr.k1}
    settings: dict[str, float] = {}
    notes = []
    f = joint.friction
    if f is not None and f.fc > 0:
        values["coulomb_friction.fc"] = f.fc
        if f.fs > f.fc:
            values.update({"stribeck_friction.ratio": f.fs / f.fc, "stribeck_friction.vs": f.vs})
        if f.asym != 0:
            values["friction_asymmetry.ratio"] = f.asym / f.fc
        if isinstance(f, TwoSEP):
            values.update({"dynamic_friction.k": f.k, "dynamic_friction.b": f.b})
    elif f is not None and f.fs > 0:
        notes.append("friction: break-away without a Coulomb level is not an effect; fs ignored")
    if f is not None and f.shape != 1.0:
        notes.append(f"friction.shape={f.shape:g}: the Stribeck effect has shape 1; the shape is not kept")
    if f is not None and f.sigma > 0:
        values["viscous_friction.sigma"] = f.sigma
        if f.sigma_asym != 0:
            values["viscous_asymmetry.ratio"] = f.sigma_asym
    if tr.k2 != 0:
        notes.append(f"transmission.k2={tr.k2:g}: no effect holds a quadratic stiffness term; ignored")
    if tr.k3 > 0:
        values["nonlinear_stiffness.k3"] = tr.k3
    if tr.damping > 0:
        values["transmission_damping.d"] = tr.damping
    if tr.backlash > 0:
        values["backlash.width"] = tr.backlash
    if tr.hysteresis is not None:
        bw = tr.hysteresis
        if (bw.a, bw.n) != (1.0, 1.0) or bw.beta != bw.gamma:
            notes.append("hysteresis: the effect has A = 1, n = 1, beta = gamma; only mu and x_u are kept")
        values.update({"transmission_hysteresis.mu": tr.hysteresis.mu,
                       "transmission_hysteresis.x_u": tr.hysteresis.x_ultimate})
    if joint.load_friction is not None:
        values.update({"load_friction.fc": joint.load_friction.fc,
                       "load_friction.viscous": joint.load_friction.viscous})
    if joint.ripple is not None:
        r = joint.ripple
        values.update({"torque_ripple.a": r.amplitude * math.cos(r.phase),
                       "torque_ripple.b": r.amplitude * math.sin(r.phase)})
        settings["torque_ripple.harmonic"] = r.harmonic
    if arm.gravity > 0:
        values["gravity.g"] = arm.gravity
    if arm.segments > 0:
        values["link_flexibility.ei"] = arm.rod_ei
        if arm.segments != 4:
            notes.append(f"arm.segments={arm.segments}: the link_flexibility effect models the rod with 4 segments")
    if arm.input_delay > 0:
        values["input_delay.delay"] = arm.input_delay
    effects = sorted({name.split(".")[0] for name in values})
    return Structure.create(effects, arm, tr.gear_ratio, values, settings), notes


@dataclass
class Problem:
    """What fit and diagnose work on: the recording's windows and the starting structure."""

    source: str
    predictor: Predictor
    base: Structure
    notes: list[str]


def read_input(args: argparse.Namespace, gear_ratio: float | None, k_m: float | None):
    """The recording named on the command line, with its column map and scales."""
    return read_recording(args.recording,
                          columns=None if args.columns is None else parse_column_map(args.columns),
                          scales=None if args.scales is None else parse_scales(args.scales),
                          gear_ratio=gear_ratio, k_m=k_m, allow_gaps=args.allow_gaps)


def load_problem(args: argparse.Namespace):
    """Recording, predictor and starting structure from the command line (one-line errors).

    A multi-joint recording (or an option only such a recording takes) gives a
    ``per_joint.JointProblems`` instead of a ``Problem``.
    """
    from . import per_joint

    for flag, value in (("--gear-ratio", args.gear_ratio), ("--k-m", args.k_m),
                        ("--window-length", args.window_length)):
        for v in value if isinstance(value, tuple) else (value,):
            if v is not None and not v > 0:
                raise CliError(f"{flag} {v:g} must be positive")
    if args.plant != "arm":
        return _drive_problem(args)
    model = None if args.model is None else read_model_file(args.model)
    if per_joint.requested(args, model):
        return per_joint.load_problems(args, model)
    notes: list[str] = []
    if model is not None:
        base, notes = structure_from_model(model, args.gear_ratio)
    else:
        if args.gear_ratio is None:
            raise CliError("--gear-ratio N is required (or a --model file that gives it)")
        effects = SEED_EFFECTS if args.base is None else effect_list(args.base)
        base = Structure.create(effects, ArmSpec(), args.gear_ratio)
    rec = read_input(args, base.gear_ratio, args.k_m)
    if not isinstance(rec, Recording):
        return per_joint.load_problems(args, model, rec)
    if rec.meta["resampled"] is not None:
        notes.append(describe_resampling(rec.meta["resampled"]))
    design = window_design(args)
    measured = Measured.from_recording(rec, base.gear_ratio)
    predictor = make_predictor(measured, design, args)
    return Problem(str(args.recording), predictor, started(base, measured, model is not None), notes)


def started(base: Structure, measured: Measured, from_model: bool) -> Structure:
    """``base`` with ranges and initial values from the recording (``identify.initial``); a
    model file's values are the user's and stay."""
    start = estimate(measured, base.nominal.link_inertia)
    return base.started(start, keep=tuple(base.values) if from_model else ())


def _drive_problem(args: argparse.Namespace) -> Problem:
    """A direct drive (``--plant linear|rotary``): its inertia, then the effects listed."""
    if args.model is not None:
        raise CliError(f"--plant {args.plant}: a direct drive starts from --base, not a --model file")
    effects = () if args.base is None else effect_list(args.base, known=plant_effects(DriveSpec()))
    rec = read_input(args, 1.0, args.k_m)
    if not isinstance(rec, Recording):
        raise CliError(f"--plant {args.plant} takes a single-joint recording")
    design = window_design(args)
    notes = [] if rec.meta["resampled"] is None else [describe_resampling(rec.meta["resampled"])]
    measured = Measured.from_recording(rec, 1.0, output=False)
    base = drive_structure(effects, PLANTS[args.plant], measured)
    return Problem(str(args.recording), make_predictor(measured, design, args), base, notes)


def drive_structure(effects, joint_type: str, measured: Measured) -> Structure:
    """A direct drive's starting structure, its size from the recording (``identify.initial``),
    not from the shipped (EMPS) DriveSpec."""
    start = estimate(measured)
    # The recorded force is what was applied: the amplifier's limit must not clip it.
    limit = max(DriveSpec.ctrl_limit, 1.01 * float(np.max(np.abs(measured.u))) / DriveSpec.k_m)
    nominal = DriveSpec(joint_type=joint_type, ctrl_limit=limit, v_eps=start.v_eps(DriveSpec.timestep, DriveSpec.v_eps))
    return Structure.create(effects, nominal, 1.0, start=start)


def fit_signals(text: str | None) -> tuple[str, ...] | None:
    """--fit-signals: a comma list among q, theta (scored as the deflection q/N - theta), tau."""
    if text is None:
        return None
    names = tuple(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    if not names or any(n not in FIT_SIGNALS for n in names):
        raise CliError(f"--fit-signals {text!r}: choose among {', '.join(FIT_SIGNALS)}")
    return tuple(dict.fromkeys(FIT_SIGNALS[n] for n in names))


def make_predictor(measured: Measured, design: WindowDesign, args: argparse.Namespace) -> Predictor:
    """The windowed predictor scoring the signals --fit-signals names, each one recorded."""
    signals = fit_signals(args.fit_signals)
    missing = [n for n, s in FIT_SIGNALS.items() if s in (signals or ()) and getattr(measured, n) is None]
    if missing:
        raise CliError(f"--fit-signals: the recording has no {missing[0]} (for this plant)")
    return Predictor(measured, design, fit_signals=signals)


def window_design(args: argparse.Namespace) -> WindowDesign:
    if not 0 <= args.lead_in <= MAX_LEAD:
        raise CliError(f"--lead-in {args.lead_in:g} must lie in [0, {MAX_LEAD:g}] s")
    return WindowDesign(length=args.window_length, seed=args.seed, lead=args.lead_in)


def run_info(command: str, args: argparse.Namespace, problem: Problem) -> dict:
    """The invocation, for run.json (paths as given)."""
    keep = {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()
            if k not in ("handler", "command")}
    return {"command": command, "arguments": keep, "recording": problem.source,
            "windows": len(problem.predictor.starts), "heldout_windows": int(problem.predictor.holdout.sum())}


def prepare(args: argparse.Namespace):
    """Output folder checked before any work, then the recording and starting structure loaded."""
    from ..report.output import OutputDir
    out = OutputDir(args.out)
    out.check()
    problem = load_problem(args)
    for note in problem.notes:
        print(f"note: {note}", file=sys.stderr)
    return out, problem


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
                        f"the recording's initial values, then seeded random ones (default {RESTARTS}; 0: none)")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from ..identify.fit import fit
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
        result = fit(problem.predictor, problem.base, max_iter=args.max_iter, progress=progress,
                     restarts=args.restarts)
    seconds = time.perf_counter() - start

    from ..report.build import write_fit
    from ..report.summary import nrmse_lines, parameter_table
    run = {**run_info("fit", args, problem), "seconds": round(seconds, 3),
           "rollouts_full_length": round(result.rollouts, 1)}
    with out.staged() as folder:
        write_fit(folder, problem.predictor, result, problem.base, problem.source, run)
    st = result.structure
    print(f"fitted {', '.join(st.effects) or 'the minimal model'} to {problem.source} "
          f"({result.iterations} iterations, {result.rollouts:.0f} full-length rollouts, {seconds:.1f} s, "
          f"best of {result.starts} start{'s' if result.starts > 1 else ''})")
    print(parameter_table(st.values, result.intervals, result.warnings, st.describe()["units"]))
    print("held-out NRMSE per signal:")
    print("\n".join(nrmse_lines(result.nrmse_test)))
    print(f"wrote {out.path}/ (fit.json, index.html, traces.rrd, PNGs)")
    return 0
