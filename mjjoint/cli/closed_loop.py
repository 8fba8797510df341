"""``mjjoint simulate --controller``: a recording of the joint in closed loop, as a lab makes one.

A reference is tracked by a saturated PD/PID position loop on the motor or the link, closed on
sensors with the testbed's resolution, noise and delay (``mjjoint.rehearse``). The CSV holds
what the sensors logged (t,u,q,theta,tau: ``mjjoint diagnose`` reads it as a real recording);
NAME.json beside it states the controller, sensors, reference and model that made it. The
plot and the Rerun recording show the true motion (every internal signal, the arm in 3D).
"""
from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
import numpy as np

from ..excitation import EXCITATIONS
from ..modelfile import ModelFile
from ..recordings import Recording, write_recording
from ..recordings.columns import name_value_pairs
from ..rehearse import Controller, LabProgram, ReferenceFile, Sensors, run_loop
from ..rehearse.controller import KINDS, SIDES, U_MAX
from ..rehearse.reference import FILE_COLUMNS, on_side
from ..report.output import staged_files, write_json
from ..sim import Simulator
from .errors import CliError

REFERENCES = ("step", "chirp", "multisine", "lab")  # or a CSV file
# Default peak of each reference [rad at the link]: a step the arm holds against gravity, and
# the lab programme's chirp level (+-0.6 deg) for the wide-band ones.
REFERENCE_AMPLITUDE = {"step": 0.15, "chirp": 0.01, "multisine": 0.01}
LOOP_OPTIONS = ("on", "gains", "limit", "reference", "bits", "noise", "delay", "sensor_seed")
SENSOR_DEFAULTS = Sensors()


def register_options(p: argparse.ArgumentParser) -> None:
    c = p.add_argument_group("closed loop (instead of an open-loop torque; see mjjoint.rehearse)")
    c.add_argument("--controller", choices=KINDS,
                   help="track --reference with this position controller; the CSV is what the sensors "
                        "logged, NAME.json beside it says how it was made")
    c.add_argument("--on", choices=SIDES, help="angle the controller closes on (default motor)")
    c.add_argument("--gains", metavar="LIST", help="kp=..,kd=..,ki=.. in N m per rad, rad/s, rad s of the "
                   "controlled angle; default on the motor kp=0.5,kd=7.5e-3 (pid: ki=2), on the link "
                   "kp=20,kd=0.3 (pid: ki=20)")
    c.add_argument("--limit", type=float, metavar="NM", help=f"saturation of u [N m] (default {U_MAX:g})")
    c.add_argument("--reference", metavar="KIND|CSV",
                   help=f"{', '.join(REFERENCES)} (default lab: the chapter's chirp, gravity sweep and steps) "
                        f"or a CSV with t and {' or '.join(FILE_COLUMNS)} [rad]; --amplitude [rad at the link], "
                        "--param, --seed and --duration shape step, chirp and multisine")
    s = p.add_argument_group("sensors (closed loop; default: the chapter's testbed)")
    s.add_argument("--bits", metavar="LIST", help=f"encoder counts per revolution as bits, 0 ideal "
                   f"(default q={SENSOR_DEFAULTS.resolver_bits},theta={SENSOR_DEFAULTS.encoder_bits})")
    s.add_argument("--noise", metavar="LIST", help=f"rms additive noise, q,theta [rad] before the counter, tau "
                   f"[N m] (default tau={SENSOR_DEFAULTS.torque_noise:g}, others 0)")
    s.add_argument("--delay", type=int, metavar="SAMPLES", help="samples from the plant to the logged and "
                   "fed-back values (default 0)")
    s.add_argument("--sensor-seed", type=int, metavar="N", help="seed of the sensor noise (default 0)")


def wanted(args: argparse.Namespace) -> bool:
    """Whether the options ask for the closed loop; a loop option without --controller is an error."""
    given = [o for o in LOOP_OPTIONS if getattr(args, o) is not None]
    if args.controller is None and given:
        raise CliError(f"--{given[0].replace('_', '-')} needs --controller pd|pid")
    return args.controller is not None


def _numbers(text: str | None, option: str, allowed: tuple[str, ...], example: str) -> dict[str, float]:
    if text is None:
        return {}
    out = {}
    for key, value in name_value_pairs(text, option, example):
        if key not in allowed:
            raise CliError(f"{option}: unknown name {key!r} (allowed: {', '.join(allowed)})")
        try:
            out[key] = float(value)
        except ValueError:
            raise CliError(f"{option}: {key}={value!r} must be a number") from None
    return out


def controller_from_args(args: argparse.Namespace) -> Controller:
    gains = _numbers(args.gains, "--gains", ("kp", "kd", "ki"), "kp=0.5,kd=0.0075")
    extra = {} if args.limit is None else {"u_max": args.limit}
    try:
        return Controller.default(args.controller, args.on or "motor", **gains, **extra)
    except ValueError as exc:
        raise CliError(f"--gains/--limit: {exc}") from None


def sensors_from_args(args: argparse.Namespace) -> Sensors:
    bits = _numbers(args.bits, "--bits", ("q", "theta"), "q=15,theta=20")
    for key, value in bits.items():
        if not value.is_integer():
            raise CliError(f"--bits {key}={value:g} must be a whole number of bits")
    noise = _numbers(args.noise, "--noise", ("q", "theta", "tau"), "tau=0.05")
    named = {"resolver_bits": bits.get("q"), "encoder_bits": bits.get("theta"), "q_noise": noise.get("q"),
             "theta_noise": noise.get("theta"), "torque_noise": noise.get("tau"), "delay": args.delay,
             "seed": args.sensor_seed}
    values = {k: int(v) if k.endswith("bits") else v for k, v in named.items() if v is not None}
    try:
        return Sensors(**values)
    except ValueError as exc:
        raise CliError(f"sensors: {exc}") from None


@dataclass(frozen=True)
class Reference:
    name: str                                      # step, chirp, multisine, lab or file
    sample: Callable[[float, float], np.ndarray]   # (rate, duration) -> angle at each sample [rad]
    side: str                                      # "link" or "motor": whose angle
    duration: float | None                         # a file's own length
    fields: dict                                   # what shaped it, for the sidecar


def reference_from_args(args: argparse.Namespace) -> Reference:
    from .simulate import signal_from_args

    name = args.reference or "lab"
    if name not in REFERENCES:
        if not Path(name).is_file():
            raise CliError(f"--reference {name}: neither one of {', '.join(REFERENCES)} nor a file")
        ref = ReferenceFile(name)
        return Reference("file", ref.sample, ref.side, ref.duration, {"path": str(ref.path)})
    if name == "lab":
        if args.param or args.amplitude is not None:
            raise CliError("--reference lab takes --seed and --duration only")
        seed = 0 if args.seed is None else args.seed
        # The programme's phases scale with the duration asked for.
        return Reference(name, lambda rate, duration: LabProgram(duration, seed=seed).sample(rate, duration),
                         "link", None, {"seed": seed})
    amplitude = REFERENCE_AMPLITUDE[name] if args.amplitude is None else args.amplitude
    shape = signal_from_args(f"--reference {name}", EXCITATIONS[name], args,
                             (("--amplitude", "amplitude", amplitude), ("--seed", "seed", args.seed)))
    return Reference(name, shape.sample, "link", None, dataclasses.asdict(shape))  # amplitude in rad here


def sidecar(args: argparse.Namespace, controller: Controller, sensors: Sensors, reference: Reference,
            rate: float, duration: float, gear_ratio: float, csv_name: str) -> dict:
    """What made the recording (no times or paths of this machine: same options, same bytes)."""
    return {"recording": csv_name, "made_by": f"mjjoint {version('mjjoint')} simulate --controller",
            "columns": {"t": "s", "u": "N m, the saturated command", "q": "rad, motor (sensed)",
                        "theta": "rad, link (sensed)", "tau": "N m, transmission (sensed)"},
            "rate": rate, "duration": duration,
            "model": "shipped arm" if args.model is None else str(args.model),
            "gear_ratio": gear_ratio, "controller": controller.describe(), "sensors": sensors.describe(),
            "reference": {"kind": reference.name, "side": reference.side, **reference.fields}}


def run(args: argparse.Namespace, model: ModelFile, rate: float) -> int:
    from .simulate import DEFAULT_DURATION, check_memory, finish, output_paths, write_outputs

    if args.excitation is not None or args.file is not None:
        raise CliError("--excitation and --file drive the motor open loop; with --controller give --reference")
    controller, sensors = controller_from_args(args), sensors_from_args(args)
    reference = reference_from_args(args)
    duration = args.duration if args.duration is not None else reference.duration or DEFAULT_DURATION
    if sensors.delay >= duration * rate:
        raise CliError(f"--delay {sensors.delay} samples is not shorter than the run ({duration * rate:.0f} samples): "
                       "nothing would be logged but the start")
    outputs = output_paths(args)
    if "csv" in outputs:
        outputs["sidecar"] = outputs["csv"].with_suffix(".json")
    sim = Simulator(model.compile(), sample_rate=rate)
    if len(sim.joints) != 1:
        raise CliError(f"--controller drives one joint; the model has {len(sim.joints)}")
    check_memory(sim, rate, duration)
    gear_ratio = sim.joints[0].gear_ratio
    theta_ref = on_side(reference.sample(rate, duration), reference.side, "link", gear_ratio)
    views = {kind: path for kind, path in outputs.items() if kind in ("plot", "rrd")}
    loop = run_loop(sim.model, theta_ref, controller, sensors, rate, keep_states=bool(views))
    cols = loop.columns
    what = f"{controller.kind} on the {controller.on}, {reference.name} reference"
    with staged_files(outputs.values()) as partial:
        if "csv" in outputs:
            write_recording(partial[outputs["csv"]], Recording(**cols, gear_ratio=gear_ratio))
            write_json(partial[outputs["sidecar"]], sidecar(args, controller, sensors, reference, rate, duration,
                                                            gear_ratio, outputs["csv"].name))
        if views:
            trace = sim.traces(loop.states, cols["u"])[0]
            sensed = {"q_over_N": cols["q"] / gear_ratio, "theta": cols["theta"], "tau": cols["tau"],
                      "theta_ref": theta_ref}
            write_outputs({kind: partial[path] for kind, path in views.items()}, [trace], sim,
                          f"closed loop {reference.name}", what, sensed)
    measured = on_side(cols["q"] if controller.on == "motor" else cols["theta"], controller.on, "link", gear_ratio)
    error = theta_ref - measured
    print(f"simulated {len(cols['t']) / rate:g} s in closed loop ({what}) at {rate:g} Hz: tracking error "
          f"rms {np.sqrt(np.mean(error ** 2)):.3g} rad at the link (sensed {controller.on}), "
          f"max |u| {np.abs(cols['u']).max():.3g} N m (limit {controller.u_max:g})")
    finish(outputs, args.spawn)
    return 0
