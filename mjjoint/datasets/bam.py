"""Rhoban BAM servo-pendulum logs: a Dynamixel XL330 swinging a mass under its own P controller.

Source: M. Duclusaud, G. Passault et al., "Extended Friction Models for the Physics Simulation
of Servo Actuators" (ICRA 2025), repository Rhoban/bam (Apache-2.0), logs from
``bam/data.bak/processed``. Each JSON log holds 6 s at 200 Hz of the output position (the
servo's ONE encoder, at the output), the goal position and whether torque was enabled; the
applied torque is not logged. It follows from the servo's firmware and motor, which BAM models
(``bam/actuator.py`` ``VoltageControlledActuator``, ``bam/dynamixel/actuator.py``
``XL330Actuator``):

    duty = clip(kp * ERROR_GAIN * (goal - position), -1, 1)      firmware P controller, PWM duty
    I    = (duty * vin - kt * w) / R                              DC motor, back-EMF ke = kt
    tau  = kt * I * torque_enable                                 at the output (BAM's kt is link side)

mjjoint's conventions (``mjjoint.recordings``): theta = position, q = GEAR_RATIO * theta (rigid
gear), u = the motor torque on the motor side = tau / GEAR_RATIO.

Choices, each checked on the 16 logs:
* The duty is computed from goal and position, not read from the log's ``load`` field (the
  Present PWM register, raw and linearly interpolated, so garbled where it wraps through 0):
  where that register is valid it equals the computed duty to rms <= 0.04 (slope 0.97-1.00),
  which also confirms ERROR_GAIN and kp's units. BAM's newer 1.75 A current limiter does not
  show in it, so it is left out.
* The back-EMF is kept IN u, from the measured motion (``back_emf=True``), not left to the
  model's viscous friction: it exists only while the H-bridge drives. With torque disabled
  (2/3 of every lift_and_drop log) the free swing decays with b ~ 0.01 N m s/rad at the
  output, a fifth to a quarter of kt^2/R = 0.05; a constant viscous coefficient cannot be both.
  ``back_emf=False`` gives the other reading (u = kt vin duty / R) for comparison. The price:
  the damping is fed forward, so a window's velocity error is not damped (windowed NRMSE 0.128
  against 0.106 on sin_time_square kp400, docs/datasets_bam.md).
* The speed is the derivative of the position (Savitzky-Golay, centred), not the log's
  ``speed`` field: that register lags the position's derivative by 4 samples (20 ms).
* The supply is the log's nominal ``vin`` (as BAM uses it): the logged ``input_volts`` scatter
  by 0.1-0.6 V rms but do not follow the estimated bus current (r^2 <= 0.11), i.e. read noise.
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from scipy.signal import savgol_filter

from ..assets import ArmSpec
from ..identify.effects import FRICTION_V_EPS
from ..identify.structure import Structure
from ..identify.windows import WindowDesign
from ..joint import JointParams
from ..modelfile import ModelFile
from ..problem import Inputs, Problem, load_problem
from ..recordings import Recording, RecordingError
from ..sim import joint_indices
from .paths import dataset_dir

DATASET = "bam_pendulum"

# XL330-M288-T gear ratio 288.35:1 (ROBOTIS e-manual, XL330-M288-T specifications).
GEAR_RATIO = 288.35
# Firmware position P controller, from BAM's XL330Actuator (bam/dynamixel/actuator.py):
# PWM counts = kp * error_counts / KP_DIVISOR, duty = PWM counts / PWM_LIMIT.
ENCODER_COUNTS = 4096     # counts per output revolution
KP_DIVISOR = 256          # "empirically observed for XL330 (manual mentions 128)"
PWM_LIMIT = 885           # default PWM limit register of the XL330: duty 1
ERROR_GAIN = ENCODER_COUNTS / (2 * math.pi) / (KP_DIVISOR * PWM_LIMIT)  # duty per (kp x rad)
# Savitzky-Golay speed for the back-EMF: 7 samples (35 ms) cubic, centred; the 5-sample
# filter the windows use for initial states amplifies the 1.5 mrad encoder step to ~0.3 rad/s.
SPEED_WINDOW = 7
SPEED_ORDER = 3


@dataclass(frozen=True)
class Motor:
    """DC motor constants seen at the output (BAM's convention): kt [N m/A] = ke [V s/rad], R [Ohm].

    ``armature`` is BAM's apparent rotor inertia at the output [kg m^2]: J_rotor * N^2.
    """

    kt: float
    r: float
    armature: float
    friction_base: float = 0.0      # BAM's Coulomb level at the output [N m] (published fit)
    friction_viscous: float = 0.0   # BAM's viscous coefficient at the output [N m s/rad]

    @property
    def gain(self) -> float:
        """Output torque per volt at standstill [N m/V]."""
        return self.kt / self.r

    @property
    def electrical_damping(self) -> float:
        """kt ke / R at the output [N m s/rad]: the back-EMF's viscous-looking torque."""
        return self.kt * self.kt / self.r


# BAM's published XL330 fits: bam/params/xl330/m{1,3,6}_sensitivity.json (commit 3af407b),
# output side, SI. ``base_mae`` there is each model's closed-loop mean |position error| [rad] on
# BAM's own XL330 logs (logdir "data/xl330"); m2, m4, m5 are listed for the table only.
BAM_PARAMS: dict[str, dict[str, float]] = {
    "m1": {"kt": 0.38429302034033563, "R": 3.588951206604558, "armature": 0.0019509450453526137,
           "q_offset": 0.019559708719558894, "friction_base": 0.0189381330982326,
           "friction_viscous": 0.004035456621843853},
    "m3": {"kt": 0.3571397933551148, "R": 2.711091789553222, "armature": 0.00222430274900321,
           "q_offset": 0.008134336389953908, "friction_base": 0.009348787927259522,
           "load_friction_base": 0.1936410776942758, "friction_viscous": 0.006994844113809709},
    "m6": {"kt": 0.3378911401596897, "R": 2.298787399903471, "armature": 0.0021173123765794786,
           "q_offset": 0.008058730308779322, "friction_base": 0.006576901417600614,
           "friction_stribeck": 0.007681868702239284, "load_friction_motor": 0.3363970560797436,
           "load_friction_external": 0.09177792244604617, "load_friction_motor_stribeck": 3.946840800336075e-06,
           "load_friction_external_stribeck": 0.12734082688777074, "load_friction_motor_quad": 0.0062496927653033895,
           "load_friction_external_quad": 0.003186138690282794, "dtheta_stribeck": 0.10006137222378013,
           "alpha": 3.26446295899839, "friction_viscous": 0.009476979761376654},
}
BAM_MAE = {"m1": 0.03172556536520317, "m2": 0.03168424792428117, "m3": 0.023441313003719166,
           "m4": 0.022474810906915742, "m5": 0.021675588911885247, "m6": 0.021841323590386423}


def _motor(name: str) -> Motor:
    p = BAM_PARAMS[name]
    return Motor(kt=p["kt"], r=p["R"], armature=p["armature"], friction_base=p["friction_base"],
                 friction_viscous=p["friction_viscous"])


# m6 is the reader's default: its friction explains the load dependence, so its motor
# constants are the least biased; m1's kt/R is 27 % lower: a smaller gain mimics friction
# that grows with the motor torque.
XL330_M6 = _motor("m6")
XL330_M1 = _motor("m1")

_META = ("mass", "length", "kp", "vin", "dt")  # kg, m, firmware units, V, s
_ENTRY = ("timestamp", "position", "goal_position", "torque_enable")


@dataclass(frozen=True, eq=False)
class ServoLog:
    """One BAM log, validated; angles in rad (0 = hanging down, as in mjjoint), t in s."""

    path: Path
    t: np.ndarray
    position: np.ndarray
    goal: np.ndarray
    enable: np.ndarray          # 1.0 torque enabled, 0.0 released
    pwm_register: np.ndarray    # the log's "load": raw Present PWM counts (NaN if absent)
    mass: float
    length: float
    kp: float
    vin: float
    dt: float
    trajectory: str
    motor: str

    @property
    def name(self) -> str:
        return f"{self.trajectory}_kp{self.kp:g}"

    def duty(self) -> np.ndarray:
        """Firmware PWM duty in [-1, 1] from the measured position error."""
        return np.clip(self.kp * ERROR_GAIN * (self.goal - self.position), -1.0, 1.0)

    def speed(self) -> np.ndarray:
        """Output speed [rad/s]: centred derivative of the position."""
        return savgol_filter(self.position, SPEED_WINDOW, SPEED_ORDER, deriv=1, delta=self.dt)

    def measured_duty(self) -> np.ndarray:
        """The logged Present PWM as a duty; NaN where interpolation through the 16-bit wrap garbled it."""
        raw = np.where(self.pwm_register > 2 ** 15 - 1, self.pwm_register - 2 ** 16, self.pwm_register)
        return np.where(np.abs(raw) <= PWM_LIMIT, raw / PWM_LIMIT, np.nan)

    def current(self, motor: Motor = XL330_M6, back_emf: bool = True) -> np.ndarray:
        """Motor current [A] (0 while torque is released)."""
        volts = self.duty() * self.vin - (motor.kt * self.speed() if back_emf else 0.0)
        return volts / motor.r * self.enable


def bam_dir() -> Path:
    """The dataset folder (``paths.data_root()/bam_pendulum``); one-line error if absent."""
    return dataset_dir(DATASET)


def log_paths(folder: Path | None = None) -> list[Path]:
    """The JSON logs of the dataset, in recording order (their names are timestamps)."""
    folder = bam_dir() if folder is None else Path(folder)
    paths = sorted(folder.glob("*.json"))
    if not paths:
        raise FileNotFoundError(f"{folder}: no BAM .json logs found")
    return paths


def _number(path: Path, where: str, value: Any, lo: float = -math.inf, lo_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RecordingError(f"{path}: {where} must be a finite number, got {value!r:.40}")
    if value < lo or (lo_open and value == lo):
        raise RecordingError(f"{path}: {where}={value!r} must be {'>' if lo_open else '>='} {lo:g}")
    return float(value)


def read_log(path: str | Path) -> ServoLog:
    """One BAM JSON log; a one-line ``RecordingError`` when it is not one or its units are off."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RecordingError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RecordingError(f"{path}: not a JSON log ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict):
        raise RecordingError(f"{path}: not a BAM log: the top level is a {type(data).__name__}, not an object")
    missing = [k for k in (*_META, "entries") if k not in data]
    if missing:
        raise RecordingError(f"{path}: not a BAM log: key {missing[0]!r} is missing")
    meta = {k: _number(path, k, data[k], 0.0, lo_open=True) for k in _META}
    motor = str(data.get("motor", ""))
    if motor != "xl330":
        raise RecordingError(f"{path}: motor {motor!r} is not supported (the firmware and motor model are the XL330's)")
    entries = data["entries"]
    if not isinstance(entries, list) or len(entries) < 2 * SPEED_WINDOW:
        raise RecordingError(f"{path}: 'entries' must be a list of at least {2 * SPEED_WINDOW} samples")
    cols: dict[str, list[float]] = {k: [] for k in (*_ENTRY, "load")}
    for i, e in enumerate(entries):
        if not isinstance(e, dict) or any(k not in e for k in _ENTRY):
            lacking = next(k for k in _ENTRY if not isinstance(e, dict) or k not in e)
            raise RecordingError(f"{path}: entry {i} has no {lacking!r}")
        for k in _ENTRY:
            v = e[k]
            if k == "torque_enable":
                if not isinstance(v, (bool, int)) or v not in (0, 1):
                    raise RecordingError(f"{path}: entry {i}: torque_enable must be true/false, got {v!r:.40}")
                v = float(v)
            cols[k].append(_number(path, f"entry {i}: {k}", v))
        load = e.get("load")
        cols["load"].append(float(load) if isinstance(load, (int, float)) and not isinstance(load, bool) else math.nan)
    t = np.asarray(cols["timestamp"])
    steps = np.diff(t)
    if not np.all(steps > 0):
        i = int(np.argmax(steps <= 0))
        raise RecordingError(f"{path}: timestamps must increase (entry {i + 1}: {t[i + 1]!r} after {t[i]!r})")
    if abs(float(np.median(steps)) - meta["dt"]) > 0.05 * meta["dt"]:
        raise RecordingError(f"{path}: timestamps step by {np.median(steps):.4g} s, not dt={meta['dt']:g} s "
                             "(timestamps must be in seconds)")
    for k in ("position", "goal_position"):
        peak = float(np.max(np.abs(cols[k])))
        if peak > 2 * math.pi:
            raise RecordingError(f"{path}: |{k}| reaches {peak:.4g}: not radians (counts or degrees?)")
    return ServoLog(path=path, t=t - t[0], position=np.asarray(cols["position"]), goal=np.asarray(cols["goal_position"]),
                    enable=np.asarray(cols["torque_enable"]), pwm_register=np.asarray(cols["load"]),
                    mass=meta["mass"], length=meta["length"], kp=meta["kp"], vin=meta["vin"], dt=meta["dt"],
                    trajectory=str(data.get("trajectory", "unknown")), motor=motor)


def to_recording(log: ServoLog, motor: Motor = XL330_M6, back_emf: bool = True) -> Recording:
    """The log in mjjoint's conventions: u = kt I / N on the motor side, q = N theta.

    theta is computed back from q, so the measured deflection q/N - theta is exactly 0: the
    servo has no second encoder and a rigid gear is all the data can say.
    """
    q = GEAR_RATIO * log.position
    u = motor.kt * log.current(motor, back_emf) / GEAR_RATIO
    meta = {"source": str(log.path), "trajectory": log.trajectory, "kp": log.kp, "vin": log.vin,
            "mass": log.mass, "length": log.length, "back_emf": back_emf, "motor": dataclasses.asdict(motor)}
    return Recording(t=log.t, u=u, q=q, theta=q / GEAR_RATIO, gear_ratio=GEAR_RATIO, meta=meta)


def read_bam(path: str | Path, motor: Motor = XL330_M6, back_emf: bool = True) -> Recording:
    """``to_recording(read_log(path))``."""
    return to_recording(read_log(path), motor, back_emf)


# ---- nominal model -------------------------------------------------------------------------

# Friction sign regularisation on the motor [rad/s] for replays at given values (BAM's): 0.017
# rad/s at the output, about one encoder count (1.5 mrad) per 0.1 s. The arm's 1 rad/s on a
# 2.5e-8 kg m^2 rotor would make BAM's Coulomb level explicit-unstable above a 0.25 ms step.
# Fits take theirs from the recording (``problem``: ``coulomb_friction.v_eps``).
SERVO_V_EPS = 5.0
# 0.5 ms: 10 steps per 5 ms sample.
SERVO_TIMESTEP = 5e-4
# The arm is not logged (BAM's Pendulum reads "arm_mass", which these logs lack): a light
# 0.1 m arm of 10 g; hub: the output horn and screws, 1e-5 kg m^2. The fitted tip mass and
# gravity.g absorb both. examples/xl330_pendulum.toml states the same bodies for the CLI.
ROD_MASS = 0.01
HUB_INERTIA = 1e-5


def nominal_arm(log: ServoLog | None = None, motor: Motor = XL330_M6, timestep: float = SERVO_TIMESTEP) -> ArmSpec:
    """The pendulum of ``log`` (mass, length; defaults 0.49 kg, 0.1 m) on the XL330.

    The rotor inertia is BAM's armature / N^2 (2.5e-8 kg m^2); u is the motor torque (k_m 1).
    """
    mass, length = (0.49, 0.1) if log is None else (log.mass, log.length)
    return ArmSpec(segments=0, rod_length=length, rod_mass=ROD_MASS, tip_mass=mass, hub_inertia=HUB_INERTIA,
                   motor_inertia=motor.armature / GEAR_RATIO ** 2, k_m=1.0, max_current=1.0, gravity=9.81,
                   timestep=timestep)


def structure(effects, log: ServoLog | None = None, motor: Motor = XL330_M6, values=None) -> Structure:
    """The pendulum with the rigid gear at ``values`` (BAM's, ``bam_values``, for replays), its
    friction's sign regularised at SERVO_V_EPS; fits start from ``problem`` instead."""
    return Structure.create(effects, nominal_arm(log, motor), GEAR_RATIO, values, {FRICTION_V_EPS: SERVO_V_EPS})


def bam_values(motor: Motor) -> dict[str, float]:
    """The Coulomb-viscous part of BAM's fit ``motor`` as mjjoint effect values (motor side)."""
    n = GEAR_RATIO
    return {"inertia.motor": motor.armature / n ** 2, "coulomb_friction.fc": motor.friction_base / n,
            "viscous_friction.sigma": motor.friction_viscous / n ** 2, "gravity.g": 9.80665}


# ---- windows over several logs ---------------------------------------------------------------

def problem(recordings: list[Recording], effects, log: ServoLog | None = None, window: float = 0.2,
            warmup: float = 0.02, seed: int = 0) -> Problem:
    """``effects`` on the pendulum of ``log`` against ``recordings`` stacked (no window spans two),
    as ``mjjoint diagnose --model examples/xl330_pendulum.toml --base EFFECTS --fit-signals q``
    takes them: the bodies the user's, the effects started from the recording's estimates, and
    only q scored (theta is q/N: ``Measured.link_encoder``)."""
    gear = dataclasses.replace(JointParams().transmission, gear_ratio=GEAR_RATIO)
    model = ModelFile(arm=nominal_arm(log), joint=JointParams(transmission=gear), given=frozenset({"arm", "transmission"}))
    design = WindowDesign(length=window, warmup=warmup, seed=seed)
    return load_problem(list(recordings), Inputs(model=model, base=tuple(effects), fit_signals=("q",), design=design))


# ---- closed-loop replay -----------------------------------------------------------------------

def replay(struct: Structure, log: ServoLog, motor: Motor = XL330_M6, back_emf: bool = True) -> np.ndarray:
    """Simulate the whole log in closed loop, the servo's controller on the SIMULATED state.

    This is how BAM scores its models (``bam/fit.py``: rollout with simulate_control): only the
    goal and torque-enable are taken from the log. The duty is recomputed every physics step
    from the held goal (the firmware's loop is much faster than the 200 Hz log). Returns the
    simulated output angle at the log's samples.
    """
    model = struct.compile()
    ji = joint_indices(model)[0]
    data = mujoco.MjData(model)
    data.qpos[ji.motor_qpos] = GEAR_RATIO * log.position[0]
    data.qpos[ji.link_qpos] = log.position[0]
    w0 = float(log.speed()[0])
    data.qvel[ji.motor_dof] = GEAR_RATIO * w0
    data.qvel[ji.link_dof] = w0
    mujoco.mj_forward(model, data)
    sub = round(log.dt / model.opt.timestep)
    gain = log.kp * ERROR_GAIN
    k_m = model.actuator_gear[ji.actuator, 0]
    out = np.empty(len(log.t))
    out[0] = log.position[0]
    for k in range(len(log.t) - 1):
        goal, enable = log.goal[k], log.enable[k]
        for _ in range(sub):
            th, w = data.qpos[ji.link_qpos], data.qvel[ji.link_dof]
            duty = min(1.0, max(-1.0, gain * (goal - th)))
            volts = duty * log.vin - (motor.kt * w if back_emf else 0.0)
            data.ctrl[ji.actuator] = motor.kt * volts / motor.r * enable / GEAR_RATIO / k_m
            mujoco.mj_step(model, data)
        out[k + 1] = data.qpos[ji.link_qpos]
    return out


def replay_errors(sim: np.ndarray, log: ServoLog) -> dict[str, float]:
    """BAM's score (mean |error| [rad]) and the NRMSE (rms error / std of the measured angle)."""
    err = sim - log.position
    return {"mae": float(np.mean(np.abs(err))),
            "nrmse": float(np.sqrt(np.mean(err ** 2)) / max(float(np.std(log.position)), 1e-12))}


# ---- BAM's own simulator, for the published parameters ---------------------------------------

def bam_rollout(log: ServoLog, params: dict[str, float], g: float = 9.80665) -> np.ndarray:
    """BAM's closed-loop rollout of a log with its friction models m1..m6 (output angle [rad]).

    A transcription of ``bam/simulate.py`` ``Simulator.step``/``rollout_log(simulate_control=
    True)`` (commit 14c382d) and ``bam/model.py`` ``Model.compute_frictions`` (commit 17d9add):
    one explicit step per 5 ms sample, friction as the torque that would stop the joint within
    the step, clipped to the friction budget; the budget's terms follow from which parameters
    ``params`` holds (m3: load_friction_base; m5/m6: the directional motor/external terms; m2,
    m4-m6: Stribeck; m6: quadratic). ``q_offset`` shifts the angle gravity sees.
    """
    p = params
    directional, stribeck, quadratic = "load_friction_motor" in p, "friction_stribeck" in p, "load_friction_motor_quad" in p
    kt, r, dt = p["kt"], p["R"], log.dt
    inertia = log.mass * log.length ** 2 + p["armature"]
    q, dq = float(log.position[0]), float(log.speed()[0])
    out = np.empty(len(log.t))
    for k in range(len(log.t)):
        out[k] = q
        volts = log.vin * min(1.0, max(-1.0, (log.goal[k] - q) * log.kp * ERROR_GAIN))
        motor = (kt * volts / r - kt * kt * dq / r) * log.enable[k]
        external = -log.mass * g * log.length * math.sin(q + p.get("q_offset", 0.0))
        budget = p["friction_base"]
        coeff = math.exp(-abs(dq / p["dtheta_stribeck"]) ** p["alpha"]) if stribeck else 0.0
        if directional:
            budget += abs(external * p["load_friction_external"] - motor * p["load_friction_motor"])
            budget += coeff * abs(external * p["load_friction_external_stribeck"]
                                  - motor * p["load_friction_motor_stribeck"])
        elif "load_friction_base" in p:
            gearbox = abs(external - motor)
            budget += (p["load_friction_base"] + coeff * p.get("load_friction_stribeck", 0.0)) * gearbox
        if stribeck:
            budget += coeff * p["friction_stribeck"]
        if quadratic and math.copysign(1, external) != math.copysign(1, motor):
            if abs(external) < abs(motor):
                budget += coeff * p["load_friction_external_quad"] * external ** 2
            elif abs(external) > abs(motor):
                budget += coeff * p["load_friction_motor_quad"] * motor ** 2
        net = motor + external
        stop = inertia / dt * dq + net
        net -= math.copysign(min(abs(stop), budget + p["friction_viscous"] * abs(dq)), stop)
        acc = net / inertia
        dq = min(100.0, max(-100.0, dq + acc * dt))
        q += dq * dt + 0.5 * acc * dt * dt
    return out
