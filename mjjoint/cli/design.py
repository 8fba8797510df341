"""``mjjoint design``: the experiment that separates two explanations a recording cannot.

The rivals are the base model plus either effect (``--rivals A,B`` over ``--base``/``--model``,
or the named effect and its ``indistinguishable_from`` rival of a diagnosis, ``--diagnosis
DIR``), each fitted to the recording REC, with 95 % intervals. The search
(``design.optimise``) returns the input, within the limits, that maximises the expected
log-likelihood ratio between them, the best few checked by rehearsing the decision; with
``--controller``, a link-angle reference for that controller (``design.loop``).
``--decide NEW_REC``: after running it, fit both rivals to the new recording and name the one
it supports (``design.decide``).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ..assets import ArmSpec
from ..identify.effects import EFFECTS
from ..identify.structure import Structure
from ..design.limits import PREDICTED
from ..rehearse.controller import KINDS, SIDES
from .closed_loop import controller_from_args
from .errors import CliError
from ..recordings import read_recording
from .options import Problem, add_problem_options, effect_names, inputs_from_args, prepare, run_info

DEFAULT_OUT = Path("out/design")

EPILOG = """\
examples:
  mjjoint design rec.csv --gear-ratio 160 --base coulomb_friction,viscous_friction,gravity,linear_stiffness \\
      --rivals input_offset,friction_asymmetry --max-torque 0.2 --max-speed 60 --angle-range 0.8 --duration 5
  mjjoint design rec.csv --diagnosis out/diagnose --signals q,theta --out out/design
  mjjoint design rec.csv --diagnosis out/diagnose --controller pd --out out/design   # a reference
  mjjoint design rec.csv --diagnosis out/diagnose --decide new.csv --out out/decide

writes DIR/experiment.csv (t,u: 'mjjoint simulate --excitation file --file DIR/experiment.csv';
with --controller t,theta_ref: 'mjjoint simulate --controller pd --limit MAX_TORQUE --reference ...'),
design.json (the expected log-likelihood ratio D, the default chirp's, the rehearsed decisions,
limits, noise floor, rivals), responses.png / responses.rrd (both rivals side by side, separation
marked), index.html and run.json; with --decide: decision.json (winner, held-out costs, realised
log-likelihood ratio, signed-rank p) and index.html. DIR appears only when complete.
"""


def signal_list(text: str) -> tuple[str, ...]:
    from ..design.limits import SIGNALS
    names = tuple(dict.fromkeys(s.strip() for s in text.split(",") if s.strip()))
    bad = [s for s in names if s not in SIGNALS]
    if not names or bad:
        raise argparse.ArgumentTypeError(f"{text!r}: signals are a comma list of {','.join(SIGNALS)}")
    return names


def noise_map(text: str) -> dict[str, float]:
    from ..design.limits import SIGNALS
    out = {}
    for item in text.split(","):
        key, _, value = item.partition("=")
        try:
            std = float(value)
        except ValueError:
            std = -1.0
        if key.strip() not in SIGNALS or not std > 0:
            raise argparse.ArgumentTypeError(f"{item!r}: give SIGNAL=STD with SIGNAL one of {','.join(SIGNALS)} "
                                             "and STD > 0, e.g. q=1e-4,tau=0.05")
        out[key.strip()] = std
    if "q" not in out:
        raise argparse.ArgumentTypeError(f"{text!r}: q's noise is needed (the deflection's includes it)")
    return out


def register(subparsers: argparse._SubParsersAction) -> None:
    from ..design.limits import Limits
    from ..design.optimise import SearchOptions
    lim, opt = Limits(), SearchOptions()
    p = subparsers.add_parser(
        "design", help="design the experiment that separates two rival explanations",
        description="Fit two rival models to a recording that cannot tell them apart, and design the input\n"
                    "(within your limits) under which their predictions differ most beyond noise and\n"
                    "parameter uncertainty; or, with --decide, name the rival a new recording supports.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_problem_options(p, DEFAULT_OUT)
    r = p.add_argument_group("rivals")
    x = r.add_mutually_exclusive_group(required=True)
    x.add_argument("--rivals", metavar="A,B", help="the two effects, each added to the starting model")
    x.add_argument("--diagnosis", type=Path, metavar="DIR",
                   help="a diagnose output folder: its final model, the named effect and its indistinguishable rival")
    g = p.add_argument_group("limits of the experiment")
    g.add_argument("--max-torque", type=float, default=lim.max_torque, metavar="NM",
                   help=f"peak motor torque |u| (default {lim.max_torque:g} N m)")
    g.add_argument("--max-speed", type=float, default=lim.max_speed, metavar="RAD_S",
                   help=f"peak motor speed (default {lim.max_speed:g} rad/s)")
    g.add_argument("--angle-range", type=float, default=lim.angle_range, metavar="RAD",
                   help=f"largest link excursion from the start (default {lim.angle_range:g} rad)")
    g.add_argument("--duration", type=float, default=lim.duration, metavar="S",
                   help=f"length of the experiment (default {lim.duration:g} s)")
    g.add_argument("--rate", type=float, default=lim.rate, metavar="HZ", help=f"sample rate (default {lim.rate:g})")
    g.add_argument("--signals", type=signal_list, default=lim.signals, metavar="LIST",
                   help="signals the new recording will hold (default q,theta,tau)")
    g.add_argument("--noise", type=noise_map, metavar="MAP",
                   help="noise std per signal, e.g. q=1e-4,theta=2e-6,tau=0.05 (default: each input's own, the "
                        "rivals' windowed prediction error on a simulated recording of it)")
    c = p.add_argument_group("closed loop (design a link-angle reference for the recording's controller)")
    c.add_argument("--controller", choices=KINDS, help="the position controller the experiment runs under")
    c.add_argument("--on", choices=SIDES, help="angle the controller closes on (default motor)")
    c.add_argument("--gains", metavar="LIST", help="kp=..,kd=..,ki=.. (default: mjjoint simulate's for the side)")
    s = p.add_argument_group("search")
    s.add_argument("--starts", type=int, default=opt.starts, metavar="K",
                   help=f"quasi-random inputs tried per family (default {opt.starts})")
    s.add_argument("--refine", type=int, default=opt.refine, metavar="K",
                   help=f"Nelder-Mead evaluations from the best (default {opt.refine})")
    s.add_argument("--draws", type=int, default=opt.draws, metavar="K",
                   help=f"parameter draws per rival for its prediction spread (default {opt.draws})")
    s.add_argument("--push", type=int, default=opt.push, metavar="K",
                   help=f"evaluations spent searching on from the default chirp where nothing found beats it by "
                        f"{100 * opt.min_gain:.0f} %% (default {opt.push})")  # %% : argparse formats help
    s.add_argument("--rehearse", type=int, default=opt.rehearse, metavar="K",
                   help=f"best inputs whose decision is rehearsed on simulated recordings (default {opt.rehearse})")
    s.add_argument("--max-iter", type=int, default=15, metavar="K", help="LM iterations of each fit (default 15)")
    p.add_argument("--decide", type=Path, metavar="NEW_REC",
                   help="the recording of the designed experiment: fit both rivals to it and name the winner")
    p.set_defaults(handler=run)


def rivals_from_diagnosis(folder: Path, nominal, gear_ratio: float) -> tuple[Structure, tuple[str, str]]:
    """(base structure, (named effect, its rival)) from a diagnose folder's diagnosis.json."""
    path = folder / "diagnosis.json"
    if not path.is_file():
        raise CliError(f"--diagnosis {folder}: no diagnosis.json there (give a 'mjjoint diagnose' output folder)")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        steps = [s for s in data.get("steps", []) if s.get("indistinguishable_from")]
        if not steps:
            raise CliError(f"--diagnosis {folder}: no step names an indistinguishable rival; nothing to separate")
        named, rival = steps[0]["effect"], steps[0]["indistinguishable_from"][0]
        final = data["final_model"]
        effects = tuple(e for e in final["effects"] if e != named)
        own = {p.name for p in EFFECTS[named].params}
        values = {k: v for k, v in final["parameters"].items() if k not in own}
        return Structure.create(effects, nominal, gear_ratio, values, final.get("settings")), (named, rival)
    except CliError:
        raise
    except (ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:  # not what diagnose writes
        what = f"no {exc}" if isinstance(exc, KeyError) else " ".join(str(exc).split())[:80]
        raise CliError(f"--diagnosis {path}: not a diagnosis.json as 'mjjoint diagnose' writes it ({what})") from None


def limits_from_args(args: argparse.Namespace):
    from ..design.limits import Limits
    return Limits(max_torque=args.max_torque, max_speed=args.max_speed, angle_range=args.angle_range,
                  duration=args.duration, rate=args.rate, signals=args.signals)


def run(args: argparse.Namespace) -> int:
    from ..design.criterion import predicted_noise
    from ..design.optimise import SearchOptions
    from ..design.rivals import Rival
    from ..identify.fit import fit

    limits = limits_from_args(args)
    try:
        options = SearchOptions(starts=args.starts, refine=args.refine, draws=args.draws, rehearse=args.rehearse,
                                push=args.push)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    if args.controller is None and (args.on or args.gains):
        raise CliError(f"--{'on' if args.on else 'gains'} needs --controller pd|pid")
    loop = None if args.controller is None else controller_from_args(
        argparse.Namespace(controller=args.controller, on=args.on, gains=args.gains, limit=None))
    if args.max_iter < 1:
        raise CliError(f"--max-iter {args.max_iter} must be at least 1")
    out, problem = prepare(args)
    if not isinstance(problem, Problem) or not isinstance(problem.base.nominal, ArmSpec):
        raise CliError("design works on one elastic joint (--plant arm, a single-joint recording)")
    inputs = inputs_from_args(args)
    new = None if args.decide is None else read_recording(args.decide, columns=inputs.columns, scales=inputs.scales,
                                                          gear_ratio=problem.base.gear_ratio, k_m=args.k_m,
                                                          allow_gaps=args.allow_gaps)
    if args.diagnosis is not None:
        base, pair = rivals_from_diagnosis(args.diagnosis, problem.base.nominal, problem.base.gear_ratio)
    else:
        pair = tuple(effect_names(args.rivals, "--rivals"))
        if len(pair) != 2:
            raise CliError(f"--rivals {args.rivals}: name exactly two effects")
        base = problem.base
    # Refused before any fit: a signal to design for with no floor to weigh it by.
    have = set(problem.predictor.signals) if args.noise is None else set(predicted_noise(args.noise, base.gear_ratio))
    missing = [s for s in limits.signals if PREDICTED[s] not in have]
    if missing:
        raise CliError(f"--signals {','.join(limits.signals)}: no noise floor for {','.join(missing)} "
                       f"(REC does not hold it; give --noise {missing[0]}=STD or leave it out of --signals)")
    structures = []
    for effect in pair:
        if effect in base.effects:
            raise CliError(f"rival {effect} is already in the starting model ({', '.join(base.effects)}); "
                           "the rivals are what the base lacks")
        try:
            structures.append(base.with_effect(effect))
        except ValueError as exc:
            raise CliError(f"--rivals: {exc}") from None
    start = time.perf_counter()
    rivals = []
    for effect, s in zip(pair, structures):
        print(f"fitting the rival with {effect} to {problem.source} ...", file=sys.stderr)
        result = fit(problem.predictor, s, max_iter=args.max_iter)
        rivals.append(Rival(effect, result.structure, result.intervals))
    rivals = tuple(rivals)
    run_data = run_info("design", args, problem)
    noise = None if args.noise is None else predicted_noise(args.noise, base.gear_ratio)
    if new is not None:
        if noise is None:  # the new recording's floor, as its design scored it (criterion.input_floor)
            noise = recording_floor(rivals, new, problem.predictor.design)
        return _decide(args, out, rivals, new, noise, problem, run_data, start)
    from ..design.export import write_design
    from ..design.optimise import design
    d = design(rivals, noise, limits, options, window=problem.predictor.design, loop=loop)
    run_data["seconds"] = round(time.perf_counter() - start, 3)
    with out.staged() as folder:
        write_design(folder, d, run_data)
    print(f"designed: {d.best.family}, {limits.duration:g} s; expected log-likelihood ratio for the rivals as "
          f"fitted {d.best.score:.3g} nats (default chirp {d.reference.score:.3g}), "
          f"{d.heldout_discrimination:.3g} over the held-out windows the decision compares")
    if d.rehearsed_ratio is not None:
        print(f"rehearsed: {d.rehearsed_ratio:.3g} nats (the smaller rehearsed decision's ratio; not a bound: how often the "
              f"realised ratio reaches each figure: docs/design-experiments.md, Calibration)")
    if d.unbeaten:
        print(f"the design is no better than the default chirp: {d.unbeaten}")
    if loop is None:
        print(f"run it: mjjoint simulate --excitation file --file {out.path / 'experiment.csv'}")
    else:
        print(f"run it: mjjoint simulate --controller {loop.kind} --on {loop.on} --limit {limits.max_torque:g} "
              f"--reference {out.path / 'experiment.csv'}")
    print(f"report: {out.path / 'index.html'}")
    return 0


def recording_floor(rivals, new, window) -> dict[str, float]:
    """The noise floor of a new recording's input: the rivals run under its torque, as the
    design scored the input (``criterion.input_floor``)."""
    import numpy as np

    from ..design.criterion import input_floor
    from ..design.response import Diverged, RivalModel
    rate = (len(new.t) - 1) / float(new.t[-1] - new.t[0])
    models = [RivalModel(r, rate, 0) for r in rivals]
    try:
        traces = [m.run(np.asarray(new.u, float)) for m in models]
    except Diverged as exc:
        raise CliError(f"--decide: a rival diverges under the new recording's torque ({exc}); give --noise") from None
    return input_floor(models, traces, window)


def _decide(args, out, rivals, new, noise, problem, run_data, start) -> int:
    from ..design.decide import decide
    from ..report.output import MARKER, write_json
    decision = decide(rivals, new, noise, problem.predictor.design, max_iter=args.max_iter)
    run_data.update(seconds=round(time.perf_counter() - start, 3), new_recording=str(args.decide))
    data = decision.as_dict()
    verdict = (f"{decision.winner} (held-out cost {decision.cost_heldout[decision.winner]:.4g} against "
               f"{decision.cost_heldout[decision.loser]:.4g} for {decision.loser}, "
               f"{100 * decision.relative_gap:.0f} % lower, signed-rank p = {decision.p_value:.2g}"
               f"{'' if decision.decisive else ': not decisive'})")
    with out.staged() as folder:
        write_json(folder / "decision.json", data)
        run_data["files"] = sorted(["decision.json", "index.html", MARKER])
        (folder / "index.html").write_text(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head><meta charset=\"utf-8\"><title>decision</title></head>\n"
            f"<body><h1>The new recording supports {decision.winner}</h1><p>{verdict}</p></body>\n</html>\n",
            encoding="utf-8")
        write_json(folder / MARKER, run_data)
    print(f"{args.decide} supports {verdict}")
    return 0
