"""``mjjoint diagnose LOG --friction-map``: the friction effects of a friction log (t, q, tau).

A friction rig's or a cobot joint's friction log (friction torque against a prescribed
motion) is diagnosed directly, without an invented inertia: ``identify.friction_map`` fits the
catalogued friction effects to tau along the measured motion and names those held-out data
need. Several logs are separate runs: each one's friction memory starts at rest.
"""
from __future__ import annotations

import argparse
import sys
import time

from ..identify.friction_map import FRICTION_EFFECTS, FrictionLog, fit_friction_map
from ..recordings import parse_column_map, parse_scales, read_signals, reading_notes
from ..report.output import OutputDir
from .errors import CliError

LAYOUT = ("t", "q", "tau")
RATE_TOLERANCE = 1e-6


def read_logs(args: argparse.Namespace) -> FrictionLog:
    """The friction logs named on the command line, one segment each; notes on resampling on stderr."""
    columns = None if args.columns is None else parse_column_map(args.columns)
    scales = None if args.scales is None else parse_scales(args.scales)
    segments, rates = [], []
    for path in args.recording:
        signals, meta = read_signals(path, columns, scales, allow_gaps=args.allow_gaps, layout=LAYOUT)
        for note in reading_notes(meta):
            print(f"note: {path}: {note}", file=sys.stderr)
        t = signals["t"]
        segments.append((t, signals["q"], signals["tau"]))
        rates.append((len(t) - 1) / (t[-1] - t[0]))
        if abs(rates[-1] / rates[0] - 1) > RATE_TOLERANCE:
            raise CliError(f"{path}: {rates[-1]:.6g} Hz; the friction logs of one diagnosis must share one sample "
                           f"rate ({args.recording[0]}: {rates[0]:.6g} Hz)")
    return FrictionLog(tuple(segments))


def run(args: argparse.Namespace, candidates: tuple[str, ...] | None) -> int:
    from ..report.friction_map import summary, write_friction_map

    for flag, given in (("--model", args.model), ("--base", args.base), ("--k-m", args.k_m), ("--joint", args.joint),
                        ("--arm", args.arm)):
        if given is not None:
            raise CliError(f"{flag} does not apply to --friction-map (a friction log: t, q, tau; "
                           "the base is Coulomb and viscous friction)")
    if args.plant != "arm":
        raise CliError("--plant does not apply to --friction-map")
    unknown = sorted(set(candidates or ()) - set(FRICTION_EFFECTS))
    if unknown:
        raise CliError(f"--candidates: {unknown[0]!r} is not a friction effect a friction log can show "
                       f"(those: {', '.join(FRICTION_EFFECTS)})")
    out = OutputDir(args.out)
    out.check()
    log = read_logs(args)
    start = time.perf_counter()
    result = fit_friction_map(log, candidates, args.min_gain, args.seed)
    seconds = time.perf_counter() - start
    run = {"command": "diagnose --friction-map", "recording": [str(p) for p in args.recording],
           "seconds": round(seconds, 3)}
    with out.staged() as folder:
        data = write_friction_map(folder, log, result, run)
    print(summary(data))
    print(f"wrote {out.path}/ (friction_map.json, friction_map.png)")
    return 0
