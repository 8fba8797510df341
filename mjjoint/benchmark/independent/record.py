"""Closed-loop recordings of the independent plant, written as the CSV ``mjjoint diagnose`` reads.

The excitation is not the development set's lab programme (down-chirp, sweep, steps): a link
reference tracked by a PD position loop on the motor encoder at the sample rate, either a slow
sine through gravity, a random-phase multisine, and a dwell-and-reverse segment (``"sweep"``), or
a robot's point-to-point moves, each a minimum-jerk profile between rests (``"moves"``). Sensors: the
motor angle quantised to ``motor_bits`` per revolution, the link angle to ``link_bits`` (read
``link_skew`` late: a timing skew between the encoders), the transmission torque through the
cell's low-pass (``torque_filter``) with white noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

from .plant import JointPlant, simulate


@dataclass(frozen=True)
class Sensors:
    motor_bits: int = 15
    link_bits: int = 20
    torque_noise: float = 0.05      # [N m] rms
    motor_noise: float = 0.0        # [rad] rms before quantisation
    link_skew: float = 0.0          # [s] the link encoder read this late against the motor's
    torque_filter: float = 0.0      # [s] time constant of the torque cell's first-order low-pass


PROGRAMS = ("sweep", "moves")


@dataclass(frozen=True)
class Excitation:
    duration: float = 6.0
    rate: float = 1000.0
    sweep: float = 0.4              # [rad] link amplitude of the slow sine
    multisine: float = 0.002        # [rad] link amplitude of each multisine component
    bandwidth: float = 6.0          # [Hz] closed-loop bandwidth of the PD loop
    seed: int = 0
    program: str = "sweep"          # one of PROGRAMS

    def __post_init__(self) -> None:
        if self.program not in PROGRAMS:
            raise ValueError(f"unknown excitation program {self.program!r} (allowed: {', '.join(PROGRAMS)})")

    def reference(self, t: np.ndarray) -> np.ndarray:
        """Link reference theta_ref(t) [rad], continuous, starting at 0 (the program's)."""
        return self._moves(t) if self.program == "moves" else self._sweep(t)

    def _moves(self, t: np.ndarray) -> np.ndarray:
        """Moves to targets drawn within +-``sweep``, each at least sweep/2 from the last, in 0.8-1.6 s
        along 10 s^3 - 15 s^4 + 6 s^5 (rest to rest), after a rest of 0.15-0.5 s."""
        rng = np.random.default_rng(self.seed)
        ref, start, at = np.zeros_like(t), 0.0, 0.0
        while start < self.duration:
            rest, move = rng.uniform(0.15, 0.5), rng.uniform(0.8, 1.6)
            target = at
            while abs(target - at) < 0.5 * self.sweep:
                target = rng.uniform(-self.sweep, self.sweep)
            s = np.clip((t - start - rest) / move, 0.0, 1.0)
            ref = np.where(t >= start, at + (target - at) * s**3 * (10.0 - 15.0 * s + 6.0 * s * s), ref)
            start, at = start + rest + move, target
        return ref

    def _sweep(self, t: np.ndarray) -> np.ndarray:
        """The slow sine's clock stops for a dwell
        of 0.8 s, in which the multisine fades out and one 2 Hz back-and-forth cycle reverses
        the motor from rest."""
        rng = np.random.default_rng(self.seed)
        f_slow = 1.0 / self.duration * rng.uniform(1.2, 1.8)
        phase = rng.uniform(0, 2 * math.pi)
        t_dwell, dwell = rng.uniform(0.45, 0.6) * self.duration, 0.8
        clock = np.where(t < t_dwell, t, np.maximum(t_dwell, t - dwell))
        ref = self.sweep * (np.sin(2 * math.pi * f_slow * clock + phase) - math.sin(phase))
        ramp = 0.1
        outside = np.clip(np.maximum(t_dwell - t, t - t_dwell - dwell) / ramp, 0.0, 1.0)
        envelope = 0.5 - 0.5 * np.cos(math.pi * outside)
        for f in rng.uniform(1.0, 15.0, 6):
            ref += envelope * self.multisine * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
        back = (t > t_dwell + 0.3) & (t < t_dwell + 0.8)
        ref[back] += 0.02 * np.sin(2 * math.pi * 2.0 * (t[back] - t_dwell - 0.3))
        return ref


def quantise(x: np.ndarray, bits: int) -> np.ndarray:
    step = 2 * math.pi / 2 ** bits
    return np.round(x / step) * step


def low_pass(x: np.ndarray, tc: float, rate: float) -> np.ndarray:
    """``x`` (sampled at ``rate``) through a first-order low-pass of time constant ``tc`` [s],
    y[n] = a y[n-1] + (1 - a) x[n] with a = exp(-1 / (rate tc)), at rest at ``x[0]`` before the
    first sample: a step's samples are the continuous lag's."""
    if tc <= 0:
        return x
    a = math.exp(-1.0 / (rate * tc))
    return lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])[0]


def record(plant: JointPlant, excitation: Excitation, sensors: Sensors, seed: int = 0,
           substeps: int = 10) -> dict[str, np.ndarray]:
    """Simulate the closed loop; return the recorded columns t, u, q, theta, tau (SI)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, excitation.duration, 1.0 / excitation.rate)
    ref = plant.gear_ratio * excitation.reference(t)
    n = plant.gear_ratio
    inertia = plant.motor_inertia + (plant.link_inertia + (plant.rod.tip_inertia if plant.rod else 0.0)) / n ** 2
    w = 2 * math.pi * excitation.bandwidth
    kp, kd = inertia * w * w, 2.0 * 0.8 * inertia * w
    q_meas = np.zeros(len(t))
    last = {"q": 0.0}

    def controller(k: int, s: np.ndarray) -> float:
        q = float(quantise(np.array(s[0] + rng.normal(0, sensors.motor_noise)), sensors.motor_bits))
        q_meas[k] = q
        v = (q - last["q"]) * excitation.rate if k else 0.0
        last["q"] = q
        vr = (ref[k] - ref[k - 1]) * excitation.rate if k else 0.0
        return float(kp * (ref[k] - q) + kd * (vr - v))

    traj = simulate(plant, t, controller, substeps)
    q_meas[-1] = float(quantise(np.array(traj.states[-1, 0] + rng.normal(0, sensors.motor_noise)),
                                sensors.motor_bits))
    theta = quantise(np.interp(t - sensors.link_skew, t, traj.states[:, 2]), sensors.link_bits)
    tau = low_pass(traj.torque, sensors.torque_filter, excitation.rate) + rng.normal(0, sensors.torque_noise, len(t))
    return {"t": t, "u": traj.u, "q": q_meas, "theta": theta, "tau": tau}


def write_csv(path: Path, cols: dict[str, np.ndarray]) -> Path:
    """The recording as plain CSV (header t,u,q,theta[,tau]: the columns ``cols`` holds),
    independent of mjjoint's writer."""
    path.parent.mkdir(parents=True, exist_ok=True)
    names = [k for k in ("t", "u", "q", "theta", "tau") if k in cols]
    np.savetxt(path, np.column_stack([cols[k] for k in names]), delimiter=",", header=",".join(names),
               comments="", fmt="%.10g")
    return path
