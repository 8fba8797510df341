"""Does the simulated joint converge with the step? The shipped step against a 100x finer one.

A real joint has no timestep: a simulation worth fitting to its recordings must give, at the
shipped 0.5 ms, what the same model gives as h -> 0. Each case runs one model at h and at
h / 100 under the same input, held at 1 kHz, and compares the motor speed and a torque by their
relative rms difference; the order of convergence is read from h, h / 2 and h / 4.

Cases: the shipped motor alone with its output cut free (a hinge drive: friction is all it
meets), the shipped arm (gear, hysteresis, flexible rod, gravity) under its down-chirp, and the
shipped 3-joint arm with every motor under one (``arm3_chirps``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..assets import load_model
from ..assets.builder import ArmSpec
from ..assets.drive import DriveSpec, build_drive
from ..assets.serial import World, build_serial_arm
from ..assets.shipped_arms import MAX_CURRENT, arm3
from ..excitation import Chirp, Impulse
from ..joint import GROUND, JointParams
from ..physics.load import LoadFriction
from ..physics.stribeck import StaticFriction
from ..physics.transmission import Transmission
from ..physics.twosep import TwoSEP
from ..sim import Simulator, Trace

SHIPPED_STEP = 5e-4
FINE = 100         # the reference step is the shipped one over this
RATE = 1000.0      # input and sample rate [Hz]
REGULARISED = LoadFriction(v_eps=0.15)  # the bearing's sign as tanh(w / 0.15 rad/s)


def rel_rms(a: np.ndarray, ref: np.ndarray) -> float:
    """rms(a - ref) / rms(ref)."""
    return float(np.sqrt(np.mean((a - ref) ** 2)) / np.sqrt(np.mean(ref ** 2)))


def free_rotor(h: float, joint: JointParams, u: np.ndarray) -> Trace:
    """The shipped motor (inertia, torque constant) with its output cut free, stepped at h."""
    arm = ArmSpec()
    drive = DriveSpec(joint_type="hinge", mass=arm.motor_inertia, k_m=arm.k_m, ctrl_limit=20.0,
                      input_offset=0.0, timestep=h)
    return Simulator(load_model(build_drive(drive, joint)), sample_rate=RATE).run(u)


def shipped_arm(h: float, joint: JointParams, u: np.ndarray) -> Trace:
    """The shipped single-joint arm with these joint physics, stepped at h."""
    return Simulator(arm=ArmSpec(timestep=h), joint=joint, sample_rate=RATE).run(u)


CURRENT_LAG = 3e-3  # [s] a current loop's time constant (``ArmSpec.input_lag``)


def lagged_arm(h: float, joint: JointParams, u: np.ndarray) -> Trace:
    """``shipped_arm`` behind a current loop's first-order lag, stepped at h."""
    return Simulator(arm=ArmSpec(timestep=h, input_lag=CURRENT_LAG), joint=joint, sample_rate=RATE).run(u)


@dataclass(frozen=True)
class Case:
    """One model under one input: ``plant`` is ``free_rotor`` or ``shipped_arm``; ``torque`` the
    trace compared besides the motor speed (``friction`` or ``tau``). ``events``: the difference
    is dominated by the instants the motor sticks or breaks free, each a step early or late, so
    its decrease with h is irregular."""

    name: str
    plant: object
    joint: JointParams
    u: np.ndarray
    torque: str
    events: bool = False


def cases() -> list[Case]:
    t = np.arange(int(RATE)) / RATE
    fs = TwoSEP().fs
    sine = fs * np.sin(2 * np.pi * t)      # 1 Hz
    sine2 = fs * np.sin(4 * np.pi * t)     # 2 Hz
    chirp = Chirp().sample(RATE, 3.0)
    step = np.where(t >= 0.1, 0.1, 0.0)
    impulse = Impulse().sample(RATE, 1.0)
    locked = JointParams(link_joint=GROUND)
    linear = JointParams(friction=None, load_friction=None, transmission=Transmission(hysteresis=None, k3=0.0))
    return [
        # 1.25 Fs: above break-away, the rotor must slide whatever the step
        Case("free rotor, 2SEP, sine 1.25 Fs, 1 Hz", free_rotor, JointParams(), 1.25 * sine, "friction"),
        Case("free rotor, 2SEP, sine 2 Fs, 1 Hz", free_rotor, JointParams(), 2.0 * sine, "friction"),
        Case("free rotor, 2SEP, sine 1.25 Fs, 2 Hz", free_rotor, JointParams(), 1.25 * sine2, "friction"),
        Case("free rotor, 2SEP, step 0.2 N m", free_rotor, JointParams(), np.where(t >= 0.1, 0.2, 0.0), "friction"),
        Case("free rotor, 2SEP, 2 ms impulse", free_rotor, JointParams(),
             np.where((t >= 0.1) & (t < 0.102), 1.25, 0.0), "friction"),
        Case("free rotor, 2SEP without lag (B = 0), sine 1.25 Fs, 1 Hz", free_rotor,
             JointParams(friction=TwoSEP(b=0.0)), 1.25 * sine, "friction"),
        Case("free rotor, static map, sine 1.25 Fs, 1 Hz", free_rotor, JointParams(friction=StaticFriction()),
             1.25 * sine, "friction"),
        Case("free rotor, static map with the exact sign, sine 1.25 Fs, 1 Hz", free_rotor,
             JointParams(friction=StaticFriction(v_eps=0.0)), 1.25 * sine, "friction"),
        Case("locked output, sine 1.25 Fs, 2 Hz", shipped_arm, locked, 1.25 * sine2, "tau"),
        Case("locked output, step 0.1 N m", shipped_arm, locked, step, "tau"),
        Case("locked output, 1.5 ms impulse (Sec. 4)", shipped_arm, locked, impulse, "tau", events=True),
        Case("shipped arm, Bouc-Wen gear alone, sine, 2 Hz", shipped_arm,
             JointParams(friction=None, load_friction=None), 0.4 * sine2, "tau"),
        Case("shipped arm, 0.3 mrad backlash, sine 1.25 Fs, 2 Hz", shipped_arm,
             JointParams(transmission=Transmission(backlash=3e-4)), 1.25 * sine2, "tau"),
        Case("shipped arm, step 0.1 N m", shipped_arm, JointParams(), step, "tau"),
        Case("shipped arm, 1.5 ms impulse (Sec. 4)", shipped_arm, JointParams(), impulse, "tau"),
        Case("shipped arm, 2SEP, 3 s down-chirp", shipped_arm, JointParams(), chirp, "tau", events=True),
        Case("shipped arm, 2SEP with load-dependent levels (g 0.3), 3 s down-chirp", shipped_arm,
             JointParams(friction=TwoSEP(load_gain=0.3)), chirp, "tau", events=True),
        Case("shipped arm, B = 0, 3 s down-chirp", shipped_arm, JointParams(friction=TwoSEP(b=0.0)), chirp, "tau"),
        Case("shipped arm, static map, 3 s down-chirp", shipped_arm, JointParams(friction=StaticFriction()), chirp,
             "tau"),
        # no friction anywhere, no hysteresis, a linear gear: the integrator's error on the linear joint
        Case("shipped arm, linear joint without friction, 3 s down-chirp", shipped_arm, linear, chirp, "tau"),
        Case("shipped arm, linear joint without friction, 3 ms current-loop lag, 3 s down-chirp", lagged_arm, linear,
             chirp, "tau"),
        # the bearing's sign regularised (it creeps instead of sticking): no link-side stick events
        Case("shipped arm, B = 0, regularised bearing, 3 s down-chirp", shipped_arm,
             JointParams(friction=TwoSEP(b=0.0), load_friction=REGULARISED), chirp, "tau"),
        Case("shipped arm, static map, regularised bearing, 3 s down-chirp", shipped_arm,
             JointParams(friction=StaticFriction(), load_friction=REGULARISED), chirp, "tau"),
    ]


@dataclass(frozen=True)
class Convergence:
    """Relative rms differences from the 100x finer step at h, h / 2 and h / 4 (``STEPS``)."""

    speed: tuple[float, ...]
    torque: tuple[float, ...]

    @property
    def order(self) -> float:
        """Observed order of convergence of the torque: the least-squares slope of log error
        against log h over the three steps (two alone are fooled where an error's sign turns)."""
        return float(np.polyfit(np.log(STEPS), np.log(self.torque), 1)[0])

    @property
    def speed_order(self) -> float:
        return float(np.polyfit(np.log(STEPS), np.log(self.speed), 1)[0])


STEPS = (1.0, 0.5, 0.25)  # the steps compared, in units of the shipped one


def measure(case: Case, h: float = SHIPPED_STEP) -> Convergence:
    ref = case.plant(h / FINE, case.joint, case.u)
    return _against(ref, [case.plant(k * h, case.joint, case.u) for k in STEPS], case.torque)


def _against(ref: Trace, runs: list[Trace], torque: str) -> Convergence:
    """The ``runs`` (at ``STEPS``) against the finer step's ``ref``: motor speed and ``torque``."""
    return Convergence(tuple(rel_rms(r.qd, ref.qd) for r in runs),
                       tuple(rel_rms(getattr(r, torque), getattr(ref, torque)) for r in runs))


# The 3-joint arm's motors under this share of their current limit: up to 600 rad/s at the
# motors (twice the seed motor's idling speed) and 2.6x the shoulder's rated gear deflection.
ARM3_SHARE = 0.5


def arm3_chirps(h: float, share: float = ARM3_SHARE) -> list[Trace]:
    """The shipped 3-joint arm (``arm3.xml``'s joints) stepped at h, every motor under the
    chapter's 3 s down-chirp at ``share`` of its current limit: one trace per joint."""
    joints = arm3()
    u = np.column_stack([Chirp(amplitude=share * MAX_CURRENT * js.k_m).sample(RATE, 3.0) for js in joints])
    return Simulator(build_serial_arm(joints, World(timestep=h)).compile(), sample_rate=RATE).run(u)


def measure_arm3(h: float = SHIPPED_STEP, share: float = ARM3_SHARE) -> list[Convergence]:
    """``measure`` for each joint of ``arm3_chirps``."""
    ref = arm3_chirps(h / FINE, share)
    runs = [arm3_chirps(k * h, share) for k in STEPS]
    return [_against(ref[j], [r[j] for r in runs], "tau") for j in range(len(ref))]


def table() -> str:
    """The markdown table of docs/design.md."""
    rows = ["| case | motor speed | torque | observed order (speed, torque) |", "|---|---|---|---|"]
    for case in cases():
        c = measure(case)
        rows.append(_row(case.name, c, case.torque))
    for j, c in enumerate(measure_arm3(), start=1):
        rows.append(_row(f"3-joint arm, every motor a down-chirp at half its current limit: joint {j}", c, "tau"))
    return "\n".join(rows)


def _row(name: str, c: Convergence, torque: str) -> str:
    return (f"| {name} | {100 * c.speed[0]:.2g} % | {100 * c.torque[0]:.2g} % ({torque}) | "
            f"{c.speed_order:.2g}, {c.order:.2g} |")


def write(out: str | Path) -> list[Path]:
    path = Path(out) / "convergence.md"
    path.parent.mkdir(parents=True, exist_ok=True)
    text = table()
    path.write_text(text + "\n")
    print(text)
    return [path]
