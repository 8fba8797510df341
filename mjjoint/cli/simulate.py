"""``mjjoint simulate``: drive a model with an excitation and write CSV, PNG and/or Rerun files."""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..assets.serial_file import read_model_file
from ..excitation import EXCITATIONS, FromFile, excitation_fields
from ..coupling.layout import NSTATE
from ..modelfile import ModelFile, from_section
from ..params import check
from ..report.output import DESTINATION_RULE, check_destination, staged_files
from ..sim import FULL, Simulator, Trace
from . import closed_loop
from .chunked import simulate_chunked
from .errors import PROG, CliError
from ..trace_recording import write_traces_csv
from .memory import HEADROOM, check_fits

DEFAULT_OUT = Path("out/simulate")
DEFAULT_DURATION = 5.0  # [s]
DEFAULT_EXCITATION = "chirp"

EPILOG = """\
examples:
  mjjoint simulate                         5 s chirp on the shipped arm -> out/simulate/trace.{csv,png,rrd}
  mjjoint simulate --excitation step --amplitude 0.1 --duration 3 --csv step.csv --plot step.png
  mjjoint simulate --excitation impulse --rate 2000 --param width=0.002 --rrd impulse.rrd
  mjjoint simulate --excitation chirp --param f_start=20 --param sweep=log --spawn
  mjjoint simulate --model examples/stiff_linear.yaml --excitation multisine --seed 3
  mjjoint simulate --excitation file --file torque.csv --csv response.csv
  mjjoint simulate --controller pd --reference lab --duration 10 --csv rec.csv   then: mjjoint diagnose rec.csv
  mjjoint simulate --controller pid --on link --gains kp=20,kd=0.3,ki=20 --limit 1 --reference step
  mjjoint simulate --controller pd --reference ref.csv --bits q=12,theta=16 --noise tau=0.1 --delay 2

outputs appear only when complete: each is written as NAME.partial-<pid>.EXT beside it and
renamed once all are written (an interrupt or error removes them). Output paths: """ + DESTINATION_RULE + """.
A run that would not fit in the memory available is refused before it starts.

excitation fields (--param KEY=VALUE):
""" + "\n".join(f"  {name:10s} " + ", ".join(f"{k}={'(required)' if v is dataclasses.MISSING else v}"
                                              for k, v in excitation_fields(cls).items())
                for name, cls in EXCITATIONS.items())


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "simulate", help="simulate the joint under a motor-torque excitation",
        description="Simulate the elastic joint driven by a motor torque u [N m], or (--controller) in closed\n"
                    "loop as a lab records it, and write the traces (CSV header t,u,q,theta,tau in SI units;\n"
                    "q motor side, theta link side).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    m = p.add_argument_group("model")
    m.add_argument("--model", type=Path, metavar="PATH",
                   help="model file (.toml, .yaml, .yml) or MJCF (.xml); default: the shipped arm. A "
                        "multi-joint model ([[joint]] file or MJCF) drives every motor with the excitation "
                        "and writes CSV columns t,u1,q1,theta1,tau1,u2,... and one plot per joint")
    m.add_argument("--rate", type=float, metavar="HZ",
                   help="sample rate; default: the model file's [simulation] sample_rate, else 1000")
    e = p.add_argument_group("excitation")
    e.add_argument("--excitation", choices=list(EXCITATIONS),
                   help=f"default: {DEFAULT_EXCITATION} (file when --file is given)")
    e.add_argument("--amplitude", type=float, metavar="NM", help="amplitude [N m at the motor] (peak for multisine)")
    e.add_argument("--duration", type=float, metavar="S",
                   help=f"simulated time; default {DEFAULT_DURATION:g} s (file: the file's length)")
    e.add_argument("--file", type=Path, metavar="CSV", help="CSV with columns t and u, for --excitation file")
    e.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help="set an excitation field (repeatable), e.g. f_start=20, sweep=log, width=0.002")
    e.add_argument("--seed", type=int, help="random seed of the multisine phases (closed loop: and of the lab reference's step levels)")
    closed_loop.register_options(p)
    o = p.add_argument_group("output (without any of these: trace.csv, trace.png and trace.rrd in --out)")
    o.add_argument("--csv", type=Path, metavar="PATH", help="CSV with header t,u,q,theta,tau")
    o.add_argument("--plot", type=Path, metavar="PATH", help="PNG of q/N and theta, delta, tau, friction")
    o.add_argument("--rrd", type=Path, metavar="PATH", help="Rerun recording of every signal and the arm in 3D")
    o.add_argument("--spawn", action="store_true",
                   help="open the Rerun recording in the viewer (written to --rrd, else to --out/trace.rrd); "
                        "without a display, one line says how to view it elsewhere")
    o.add_argument("--out", type=Path, default=DEFAULT_OUT, metavar="DIR", help=f"default: {DEFAULT_OUT}")
    p.set_defaults(handler=run)


def _parse_value(key: str, text: str, default: Any) -> Any:
    """A --param value typed like the field's default (text for text fields and unknown keys)."""
    kind = type(default)
    if kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            raise CliError(f"--param {key}={text!r} must be {'an integer' if kind is int else 'a number'}") from None
    return text


def excitation_from_args(args: argparse.Namespace) -> tuple[str, Any]:
    """(name, excitation) the options describe; the excitation validated by its own dataclass."""
    name = args.excitation or ("file" if args.file is not None else DEFAULT_EXCITATION)
    cls = EXCITATIONS[name]
    excitation = signal_from_args(f"--excitation {name}", cls, args, (
        ("--amplitude", "amplitude", args.amplitude),
        ("--file", "path", None if args.file is None else str(args.file)), ("--seed", "seed", args.seed)))
    return name, excitation


def signal_from_args(what: str, cls: type, args: argparse.Namespace, flags) -> Any:
    """``cls`` (option ``what``) built from ``--param KEY=VALUE`` and ``flags`` ((option, field, value or None), ...)."""
    fields = excitation_fields(cls)
    values: dict[str, Any] = {}
    for item in args.param:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise CliError(f"--param {item!r} must be KEY=VALUE")
        values[key] = _parse_value(key, text.strip(), fields.get(key))
    for flag, key, value in flags:
        if value is not None:
            if key not in fields:
                raise CliError(f"{flag} does not apply to {what} (its fields: {', '.join(fields)})")
            values[key] = value
    if cls is FromFile and "path" not in values:
        raise CliError("--excitation file needs --file PATH")
    return from_section(cls, values, what.split()[-1])


def output_paths(args: argparse.Namespace) -> dict[str, Path]:
    """Requested outputs (kind -> path), checked writable before any simulation time is spent.

    Nothing is created here: the files and missing folders appear when the outputs are written.
    """
    chosen = {"csv": args.csv, "plot": args.plot, "rrd": args.rrd}
    option = {kind: f"--{kind}" for kind in chosen}
    if not any(chosen.values()) and not args.spawn:
        chosen = {"csv": args.out / "trace.csv", "plot": args.out / "trace.png", "rrd": args.out / "trace.rrd"}
        option = dict.fromkeys(chosen, "--out")
    elif args.spawn and args.rrd is None:  # the viewer opens a finished file
        chosen["rrd"], option["rrd"] = args.out / "trace.rrd", "--out"
    out = {kind: path for kind, path in chosen.items() if path is not None}
    if len({path.resolve() for path in out.values()}) < len(out):
        raise CliError(f"{', '.join(option[k] for k in out)} must name different files (each is written whole)")
    for kind, path in out.items():
        if path.is_dir():
            raise CliError(f"{path}: is a directory, not a file")
        allowed = _suffixes(kind)
        if path.suffix.lower() not in allowed:
            raise CliError(f"{path}: {option[kind]} writes {' or '.join(sorted(allowed))}, not "
                           f"{path.suffix or 'a name without a suffix'!r}")
        check_destination(path, option[kind])
        if path.exists() and not os.access(path, os.W_OK):
            raise CliError(f"{path}: permission denied")
    return out


def _suffixes(kind: str) -> set[str]:
    """The file names an output of ``kind`` can be written as: a recording as .csv, the viewer's
    log as .rrd, a plot in any format matplotlib writes."""
    if kind == "plot":
        from matplotlib.backend_bases import FigureCanvasBase  # matplotlib only when a plot is asked for
        return {f".{ext}" for ext in FigureCanvasBase.get_supported_filetypes()}
    return {f".{kind}"}


def check_memory(sim: Simulator, rate: float, duration: float) -> None:
    """Refuse a run whose arrays would not fit in the memory available, before allocating them.

    Per sample, 8 bytes for: the input (and its per-joint copy), the full-physics states twice
    (the chunks and their stacked copy), and each joint's traces (9 signals, its plugin states
    and the positions of every joint for the 3D view); times ``HEADROOM`` for the writers' copies.
    """
    if not 0 < duration < math.inf:  # before it counts samples: nan would count as nan GB
        raise CliError(f"--duration={duration:g} s must be positive and finite")
    joints = len(sim.joints)
    nstate = mujoco.mj_stateSize(sim.model, FULL)
    per_sample = 8 * (1 + joints + 2 * nstate + joints * (9 + NSTATE + sim.model.nq))
    samples = rate * duration
    check_fits(HEADROOM * per_sample * samples, f"--duration {duration:g} s at --rate {rate:g} Hz "
               f"({samples:.3g} samples, {HEADROOM * per_sample:.0f} bytes each)",
               "shorten --duration or lower --rate")


def _summary(name: str, excitation, trace: Trace, rate: float) -> str:
    amp = getattr(excitation, "amplitude", None)
    what = f"{name}" + (f" {amp:g} N m" if amp is not None else f" {excitation.path}")
    return (f"simulated {trace.t[-1] + 1 / rate:g} s of {what} at {rate:g} Hz: "
            f"theta in [{np.degrees(trace.theta.min()):.3g}, {np.degrees(trace.theta.max()):.3g}] deg, "
            f"max |delta| {1e3 * np.abs(trace.delta).max():.3g} mrad, max |tau| {np.abs(trace.tau).max():.3g} N m")


def write_outputs(paths: dict[str, Path], traces: list[Trace], sim: Simulator, name: str, excitation,
                  sensed: dict[str, np.ndarray] | None = None) -> None:
    """Write the traces to ``paths`` (kind -> path: csv, plot or plot1, plot2, ..., rrd); ``sensed``
    signals of a single trace go into the .rrd beside it (``log_traces``)."""
    many = len(traces) > 1
    if "csv" in paths:
        if many:
            write_traces_csv(paths["csv"], traces)
        else:
            traces[0].to_csv(paths["csv"])
    plots = [path for kind, path in paths.items() if kind.startswith("plot")]  # in joint order
    if plots:
        from .plot import plot_trace  # matplotlib only when a plot is asked for
        for j, (trace, path) in enumerate(zip(traces, plots), start=1):
            plot_trace(trace, path, title=f"mjjoint simulate: {excitation}" + (f", joint {j}" if many else ""))
    if "rrd" in paths:
        from ..viz.rerun_log import log_traces  # rerun only when asked for
        log_traces({f"joint{j}": tr for j, tr in enumerate(traces, start=1)} if many else traces[0],
                   model=sim.model, recording_name=f"simulate {name}", rrd_path=paths["rrd"], sensed=sensed)


def finish(outputs: dict[str, Path], spawn: bool) -> None:
    """List the written outputs; with ``spawn``, open the .rrd or say how to view it elsewhere."""
    if outputs:
        print("wrote " + ", ".join(str(p) for p in outputs.values()))
    if spawn:
        from ..viz.viewer import how_to_view, open_viewer
        problem = open_viewer(outputs["rrd"])
        if problem is not None:
            print(f"{PROG}: {problem}: {how_to_view(outputs['rrd'])}", file=sys.stderr)


def _note_clipping(sim: Simulator, u: np.ndarray) -> None:
    """Say so where the input exceeds an actuator's range: MuJoCo clips it, as an amplifier would,
    and the traces show the clipped torque."""
    clipped = np.any(sim.applied(u) != u, axis=1)
    if clipped.any():
        top = float(np.min(np.abs(sim.applied(np.full((1, u.shape[1]), np.inf)))))
        print(f"{PROG}: note: u exceeds the motor's range of {top:g} N m on {clipped.mean():.0%} of the samples and "
              "is clipped there ([arm] max_current x k_m sets the range)", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    model = read_model_file(args.model) if args.model is not None else ModelFile()
    rate = model.sample_rate if args.rate is None else check("--rate", args.rate, 0.0, lo_open=True)
    if closed_loop.wanted(args):
        return closed_loop.run(args, model, rate)
    name, excitation = excitation_from_args(args)
    duration = args.duration
    if duration is None:
        duration = excitation.duration if isinstance(excitation, FromFile) else DEFAULT_DURATION
    outputs = output_paths(args)
    sim = Simulator(model.compile(), sample_rate=rate)
    check_memory(sim, rate, duration)
    u = excitation.sample(rate, duration)
    u_joints = np.repeat(u[:, None], len(sim.joints), axis=1)
    _note_clipping(sim, u_joints)
    traces = simulate_chunked(sim, u_joints)
    many = len(traces) > 1
    if many and "plot" in outputs:  # one plot per joint: NAME1.png, NAME2.png, ...
        path = outputs.pop("plot")
        outputs.update({f"plot{j}": path.with_stem(f"{path.stem}{j}") for j in range(1, len(traces) + 1)})
    with staged_files(outputs.values()) as partial:
        write_outputs({kind: partial[path] for kind, path in outputs.items()}, traces, sim, name, excitation)
    for j, trace in enumerate(traces, start=1):
        print((f"joint {j}: " if many else "") + _summary(name, excitation, trace, rate))
    finish(outputs, args.spawn)
    return 0
