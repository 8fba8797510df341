"""The options ``fit`` and ``diagnose`` share, and the problem they describe.

The recording, the starting structure from ``--base`` (effect names) or ``--model`` (a model
file whose terms are mapped onto effect names, its values as initial values), and the
prediction windows, as ``problem.Inputs``; ``problem.load_problem`` builds the problem, naming
the options in its messages.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from ..identify.effects import EFFECTS
from ..identify.windows import MAX_LEAD, WindowDesign
from ..problem import PLANTS, Inputs, Problem, load_problem
from ..recordings import parse_column_map, parse_scales
from ..report.output import DESTINATION_RULE
from .errors import CliError

MINIMAL = "minimal"
# How the problem's inputs are spelled on the command line, for its messages.
NAMES = {"gear_ratio": "--gear-ratio", "k_m": "--k-m", "base": "--base", "model": "--model", "plant": "--plant",
         "joints": "--joint", "fit_signals": "--fit-signals", "arm": "--arm"}
FIT_SIGNALS = {"q": "q", "theta": "delta", "tau": "tau"}  # --fit-signals name -> the cost's signal


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
    p.add_argument("recording", type=Path, nargs="+", metavar="REC",
                   help="recording: .csv, .tsv, .txt or .dat text table (t,u,q,theta[,tau]; several joints: "
                        "t,u1,q1,theta1,...), .npz, .mat, .h5, .parquet, .json/.jsonl, .mcap or a ROS 2 bag "
                        "folder; several single-joint recordings are stacked as separate segments (no window "
                        "spans two)")
    r = p.add_argument_group("recording")
    r.add_argument("--gear-ratio", type=numbers, metavar="N",
                   help="gear ratio (required unless --model gives it); N1,N2,... one per joint")
    r.add_argument("--columns", metavar="MAP", help="file names of the signals, e.g. t=time,u=cur,q=qm,theta=ql; a source may be an "
                        "expression of the file's values, u='0.338/288.35*cur', q='288.35*pos' "
                        "(docs/recordings.md)")
    r.add_argument("--scales", metavar="MAP", help="factors to SI, e.g. q=deg,theta=deg,u=2.5")
    r.add_argument("--allow-gaps", action="store_true",
                   help="interpolate across time steps longer than 5 median periods, and across samples "
                        "with a non-finite value (dropouts), instead of refusing")
    r.add_argument("--k-m", type=numbers, metavar="K",
                   help="torque constant [N m/A]: u is recorded as a current; K1,K2,... one per joint")
    r.add_argument("--joint", type=joint_numbers, metavar="J[,K]",
                   help="joints of a multi-joint recording to work on (default: all)")
    m = p.add_argument_group("starting model (default: the seed paper's full joint)")
    m.add_argument("--model", type=Path, metavar="FILE",
                   help="model file (.toml/.yaml): its arm (bodies, timestep); its terms become effects, "
                        "its values initial values; a [[joint]] file gives each joint of a multi-joint "
                        "recording its own")
    m.add_argument("--base", metavar="LIST",
                   help="comma list of effect names ('minimal': none); with --model, the effects to start "
                        "from on the model's arm (the file's values where it gives them)")
    m.add_argument("--arm", type=Path, metavar="FILE",
                   help="the whole arm of a multi-joint recording ([[joint]] model file or MJCF with an "
                        "mjjoint.joint per joint): MuJoCo computes the inertia, Coriolis and gravity forces "
                        "the other joints' measured motion puts on each joint diagnosed; a [[joint]] file is "
                        "also the starting model unless --model or --base is given")
    m.add_argument("--plant", choices=PLANTS, default="arm",
                   help="arm: the elastic joint (q and theta measured); linear or rotary: a direct drive, "
                        "one joint and no gear, only q used (map theta to q's column, e.g. theta=qm); "
                        "default arm")
    w = p.add_argument_group("prediction windows")
    w.add_argument("--window-length", type=float, default=WindowDesign.length, metavar="S",
                   help=f"prediction horizon of each window (default {WindowDesign.length:g} s)")
    w.add_argument("--lead-in", type=float, default=WindowDesign.lead, metavar="S",
                   help="longest simulated lead-in of a window that starts at rest, for 2SEP's "
                        f"states (default {WindowDesign.lead:g} s; 0: none, which leaves the lag's windup at "
                        "rest unknown and biases its gain)")
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


def effect_list(text: str, option: str = "--base") -> tuple[str, ...]:
    """The effects of a starting structure ('minimal' alone: none)."""
    names = effect_names(text, option, (MINIMAL, *EFFECTS))
    if names == [MINIMAL]:
        return ()
    if MINIMAL in names:
        raise CliError(f"{option}: '{MINIMAL}' means no effect; do not list it with others")
    return tuple(names)  # prerequisites: checked where the structure is built (problem.load_problem)


def inputs_from_args(args: argparse.Namespace) -> Inputs:
    """The problem's inputs from the command line (one-line errors naming the option)."""
    if not 0 < args.window_length < math.inf:
        raise CliError(f"--window-length {args.window_length:g} must be positive and finite")
    if args.seed < 0:
        raise CliError(f"--seed {args.seed} must be 0 or more")
    if not 0 <= args.lead_in <= MAX_LEAD:
        raise CliError(f"--lead-in {args.lead_in:g} must lie in [0, {MAX_LEAD:g}] s")
    return Inputs(gear_ratio=args.gear_ratio, k_m=args.k_m,
                  base=None if args.base is None else effect_list(args.base), model=args.model,
                  plant=args.plant, joints=args.joint,
                  design=WindowDesign(length=args.window_length, seed=args.seed, lead=args.lead_in),
                  columns=None if args.columns is None else parse_column_map(args.columns),
                  scales=None if args.scales is None else parse_scales(args.scales), allow_gaps=args.allow_gaps,
                  fit_signals=fit_signals(args.fit_signals), arm=args.arm)


def fit_signals(text: str | None) -> tuple[str, ...] | None:
    """--fit-signals: a comma list among q, theta (scored as the deflection q/N - theta), tau."""
    if text is None:
        return None
    names = tuple(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    if not names or any(n not in FIT_SIGNALS for n in names):
        raise CliError(f"--fit-signals {text!r}: choose among {', '.join(FIT_SIGNALS)}")
    return tuple(dict.fromkeys(FIT_SIGNALS[n] for n in names))


def run_info(command: str, args: argparse.Namespace, problem: Problem) -> dict:
    """The invocation, for run.json (paths as given)."""
    keep = {k: (str(v) if isinstance(v, Path) else [str(x) for x in v] if k == "recording" else v)
            for k, v in vars(args).items() if k not in ("handler", "command")}
    return {"command": command, "arguments": keep, "recording": problem.source,
            "windows": len(problem.predictor.starts), "heldout_windows": int(problem.predictor.holdout.sum())}


def prepare(args: argparse.Namespace) -> tuple:
    """Output folder checked before any work, then the recording and starting structure loaded:
    (``OutputDir``, ``Problem`` or, for a multi-joint recording, ``JointProblems``)."""
    from ..report.output import OutputDir
    out = OutputDir(args.out)
    out.check()
    recording = args.recording[0] if len(args.recording) == 1 else list(args.recording)
    problem = load_problem(recording, inputs_from_args(args), NAMES)
    for note in problem.notes:
        print(f"note: {note}", file=sys.stderr)
    return out, problem
