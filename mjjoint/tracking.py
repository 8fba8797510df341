"""Scripted joint-space tracking of a (multi-joint) arm with a motor-side PD controller per joint."""
from __future__ import annotations

import mujoco
import numpy as np

from .params import check
from .sim import FULL, Simulator, Trace, check_diverged, sample_velocity, step_held


def track(sim: Simulator, q_ref_link: np.ndarray, kp, kd,
          initial_state: np.ndarray | None = None) -> list[Trace]:
    """Follow link angles ``q_ref_link`` (n, njoint) with a PD controller on each motor.

    u_j = kp_j (N_j theta_ref_j - q_j) + kd_j (N_j theta_ref_j' - q_j'), from the motor-side
    q and q' at each sample (the chapter's setups measure the motor encoder), clipped to the
    actuator range and held for the sample. Per-sample Python: a scripting tool, not a
    rollout. Returns one Trace per joint, u being the torque applied.
    """
    ref = np.asarray(q_ref_link, dtype=float)
    nj = len(sim.joints)
    if ref.ndim != 2 or ref.shape[1] != nj or len(ref) < 1:
        raise ValueError(f"q_ref_link must have shape (n, {nj}), got {ref.shape}")
    if not np.all(np.isfinite(ref)):
        raise ValueError("q_ref_link contains NaN or inf")
    kp = np.broadcast_to(np.asarray(kp, float), (nj,))
    kd = np.broadcast_to(np.asarray(kd, float), (nj,))
    for name, g in (("kp", kp), ("kd", kd)):
        for v in g:
            check(name, v, 0.0)
    m, d = sim.model, sim.data
    gear = np.array([j.gear_ratio for j in sim.joints])
    km = np.array([j.k_m for j in sim.joints])
    mq = [j.motor_qpos for j in sim.joints]
    md = [j.motor_dof for j in sim.joints]
    act = [j.actuator for j in sim.joints]
    if min(act) < 0:
        raise ValueError("every joint needs an actuator on its motor joint")
    limited = m.actuator_ctrllimited[act].astype(bool)
    lo = np.where(limited, m.actuator_ctrlrange[act, 0] * km, -np.inf)
    hi = np.where(limited, m.actuator_ctrlrange[act, 1] * km, np.inf)
    ref_rate = np.gradient(ref, 1.0 / sim.sample_rate, axis=0) if len(ref) > 1 else np.zeros_like(ref)

    x0 = sim.initial_state() if initial_state is None else np.asarray(initial_state, float)
    mujoco.mj_setState(m, d, x0, FULL)
    d.ctrl[:] = 0.0
    states = np.empty((len(ref) + 1, len(x0)))
    states[0] = x0
    u = np.empty_like(ref)
    w_before = np.full(m.nv, np.nan)
    for k in range(len(ref)):
        w = sample_velocity(d.qvel[md], w_before[md])  # the motor speed at the sample, as the traces give it
        u[k] = np.clip(kp * (gear * ref[k] - d.qpos[mq]) + kd * (gear * ref_rate[k] - w), lo, hi)
        w_before = step_held(m, d, act, u[k] / km, u[k - 1] / km if k else 0.0, sim.substeps)
        mujoco.mj_getState(m, d, states[k + 1], FULL)
    check_diverged(states[1:], x0[0])
    return sim.traces(states[:-1], u)
