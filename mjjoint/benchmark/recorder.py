"""Closed-loop lab recordings of a simulated joint, with the sensors of the chapter's testbed.

The truth is driven the way the lab joint is (Sec. 4): a motor-side PD position loop tracks a
reference program — a down-chirp 30 -> 1 Hz, a slow sweep across the workspace where gravity
shows, and steps — closing the loop on QUANTISED measurements (15-bit resolver per motor
revolution, 20-bit link encoder); the recording logs the controller's command u, the quantised
angles and a noisy torque cell. The controller runs once per sample in Python (this generates
test data; it is not on any fitting path); the plant, including an input delay if the truth
has one, is MuJoCo with the mjjoint plugin.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from ..assets import ArmSpec, build_arm, load_model
from ..coupling.kernels import joint_catch_up, transmitted
from ..coupling.layout import NSTATE
from ..joint import JointParams
from ..params import check
from ..sensors import LINK_ENCODER_BITS, RESOLVER_BITS, Sensors, lsb, quantise  # noqa: F401 (re-exported)
from ..sim import joint_indices



@dataclass(frozen=True)
class LabProgram:
    """Link-side reference program; amplitudes in rad. Durations scale with ``duration``."""

    duration: float = 20.0
    chirp_amplitude: float = 0.01    # +-0.6 deg around the hanging position
    sweep_amplitude: float = 1.2     # +-69 deg: gravity torque spans most of its range
    step_amplitude: float = 0.15
    seed: int = 0

    def __post_init__(self) -> None:
        check("duration", self.duration, 2.0, 3600.0)

    def reference(self, t: np.ndarray) -> np.ndarray:
        """theta_ref(t): 40 % down-chirp, 30 % slow sweep, 30 % steps (random levels per seed)."""
        rng = np.random.default_rng(self.seed)
        T = self.duration
        ref = np.zeros_like(t)
        t1, t2 = 0.4 * T, 0.7 * T
        a = t < t1
        # Down-chirp 30 -> 1 Hz: instantaneous frequency f(t) = 30 * (1/30)^(t/t1).
        k = math.log(1 / 30) / t1
        phase = 2 * math.pi * 30 * (np.exp(k * t[a]) - 1) / k
        ref[a] = self.chirp_amplitude * np.sin(phase) * np.minimum(1.0, t[a] / 0.2)
        b = (t >= t1) & (t < t2)
        tb = t[b] - t1
        ref[b] = self.sweep_amplitude * 0.5 * (1 - np.cos(2 * math.pi * tb / (t2 - t1)))
        ref[b] *= 1 if rng.random() < 0.5 else -1
        c = t >= t2
        levels = rng.uniform(-1, 1, 6) * self.step_amplitude
        idx = np.minimum(((t[c] - t2) / ((T - t2) / 6)).astype(int), 5)
        ref[c] = levels[idx]
        # Smooth the step edges a little (a trajectory generator would).
        return ref


@dataclass(frozen=True)
class Controller:
    """Motor-side PD on quantised q, with a first-order velocity filter."""

    kp: float = 0.5           # [N m/rad] ~15 Hz bandwidth on the 5.7e-5 kg m^2 motor-side inertia
    kd: float = 7.5e-3        # [N m s/rad] damping ratio ~0.7
    velocity_cutoff: float = 200.0   # [Hz]
    u_max: float = 1.3        # [N m] rated torque of the 400 W motor


def record(arm: ArmSpec, joint: JointParams, program: LabProgram = LabProgram(),
           controller: Controller = Controller(), sensors: Sensors = Sensors(), rate: float = 1000.0):
    """Run the closed loop; returns dict of columns t,u,q,theta,tau (measured, SI)."""
    model = load_model(build_arm(arm, joint, scene=False))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    ji = joint_indices(model)[0]
    sub = int(round(1.0 / (rate * model.opt.timestep)))
    n = int(round(program.duration * rate))
    t = np.arange(n) / rate
    q_ref = program.reference(t) * ji.gear_ratio
    rng = np.random.default_rng(sensors.seed)
    alpha = 1 - math.exp(-2 * math.pi * controller.velocity_cutoff / rate)
    cols = {k: np.empty(n) for k in ("t", "u", "q", "theta", "tau")}
    q_prev, v_filt = 0.0, 0.0
    adr = int(model.plugin_stateadr[ji.instance])
    steps = ji.steps(model)
    for i in range(n):
        q = quantise(np.array(data.qpos[ji.motor_qpos]), sensors.resolver_bits).item()
        th = quantise(np.array(data.qpos[ji.link_qpos]), sensors.encoder_bits).item()
        v_filt += alpha * ((q - q_prev) * rate - v_filt) if i else 0.0
        q_prev = q
        u = controller.kp * (q_ref[i] - q) - controller.kd * v_filt
        u = min(max(u, -controller.u_max), controller.u_max)
        st = data.plugin_state[adr:adr + NSTATE].copy()
        joint_catch_up(ji.block, st, data.qpos[ji.motor_qpos], data.qvel[ji.motor_dof],
                       data.qpos[ji.link_qpos], data.qvel[ji.link_dof], data.time, *steps)
        tau = transmitted(ji.block, st, data.qpos[ji.motor_qpos], data.qvel[ji.motor_dof],
                          data.qpos[ji.link_qpos], data.qvel[ji.link_dof])
        cols["t"][i], cols["u"][i], cols["q"][i], cols["theta"][i] = data.time, u, q, th
        cols["tau"][i] = tau + rng.normal(0.0, sensors.torque_noise)
        data.ctrl[ji.actuator] = u / ji.k_m
        for _ in range(sub):
            mujoco.mj_step(model, data)
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:  # MuJoCo reset the data
            raise RuntimeError(f"truth simulation diverged near t = {cols['t'][i]:.3f} s")
    return cols
