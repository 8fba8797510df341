"""What the mjjoint.control environments give: mean reward of two simple policies per task and
arm, the cost of an environment step, the stiff-joint limit and the import cost.

  zero   no current: what the arm does on its own (hanging; for damp, the passive decay);
  pd     a motor-side PD per joint on the sensors only (quantised motor angle, its filtered
         difference as velocity), set point N x the link's goal (reference, target, 0): the
         lab's loop (mjjoint.rehearse.Controller), in amperes, no gravity model;
  torque motor torque -g T/N per joint from the torque cell (g = 4, noise included): the motor
         gives way to the rod's pull on the hub, which damps the rod; no position loop.

Mean reward over one episode of the task's default length, seed 0, default sensors. Step cost:
thread CPU time per env.step of the zero policy, best of --repeats episodes, beside the bare
mj_step of the same model for the same 1 ms (2 physics steps). Rigid limit: the link of a
stiff, frictionless joint against build_rigid_arm over the 1 s current program of
tests/test_control_env.py, h = 50 us. Import: `import mjjoint`, then `import mjjoint.control`,
in a fresh interpreter, one after the other (best of --repeats).

    python scripts/control_baselines.py
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time

import mujoco
import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco import wrapper

from mjjoint import ArmSpec, JointParams, Transmission, build_arm
from mjjoint.rehearse import Controller
from mjjoint.control import TASKS, JointSensors, build_rigid_arm, load

MODELS = ("scene.xml", "arm2_planar.xml", "arm3.xml")


def pd_policy(env):
    """The lab's motor-side PD (rehearse.Controller) per joint, on the observations only."""
    c, dt = Controller(), env.control_timestep()
    joints = env.physics.joints
    n_gear = np.array([ji.gear_ratio for ji in joints])
    k_m = np.array([ji.k_m for ji in joints])
    alpha = 1 - np.exp(-2 * np.pi * c.velocity_cutoff * dt)
    spec = env.action_spec()
    state = {"q": None, "v": np.zeros(len(joints))}

    def act(obs):
        goal = obs.get("reference", obs.get("target", np.zeros(len(joints))))
        q = obs["motor_angle"]
        if state["q"] is not None:
            state["v"] += alpha * ((q - state["q"]) / dt - state["v"])
        state["q"] = q
        u = np.clip(c.kp * (n_gear * goal - q) - c.kd * state["v"], -c.u_max, c.u_max)
        return np.clip(u / k_m, spec.minimum, spec.maximum)
    return act


def torque_policy(env, gain: float = 4.0):
    """Motor torque -gain T/N per joint, T the torque cell's reading, in amperes."""
    joints = env.physics.joints
    scale = np.array([-gain / (ji.gear_ratio * ji.k_m) for ji in joints])
    spec = env.action_spec()
    return lambda obs: np.clip(scale * obs["joint_torque"], spec.minimum, spec.maximum)


def run(env, policy=None) -> tuple[float, float]:
    """(mean reward, CPU seconds per step) of one episode."""
    ts = env.reset()
    act = policy(env) if policy else (lambda obs: np.zeros(env.action_spec().shape))
    rewards, t0 = [], time.thread_time()
    while not ts.last():
        ts = env.step(act(ts.observation))
        rewards.append(ts.reward)
    return float(np.mean(rewards)), (time.thread_time() - t0) / len(rewards)


def bare_step(model: str, steps: int = 2000) -> float:
    physics = load("hold", model).physics
    m, d = physics.model.ptr, physics.data.ptr
    t0 = time.thread_time()
    mujoco.mj_step(m, d, 2 * steps)
    return (time.thread_time() - t0) / steps


def rigid_limit() -> dict[float, float]:
    arm = ArmSpec(timestep=5e-5)
    acts = np.repeat(np.random.default_rng(0).uniform(-3, 3, 10), 100)[:, None]
    rigid = dm_mujoco.Physics.from_model(wrapper.MjModel(build_rigid_arm(arm).compile()))
    rigid.reset(0)
    ref = []
    for u in acts:
        rigid.set_control(u)
        rigid.step(20)
        ref.append(rigid.data.qpos[0])
    out = {}
    for k1 in (1e4, 1e5, 1e6):
        joint = JointParams(friction=None, load_friction=None,
                            transmission=Transmission(k1=k1, k3=0.0, hysteresis=None))
        env = load("track", build_arm(arm, joint), task_kwargs={"random": 0, "sensors": JointSensors(
            resolver_bits=None, encoder_bits=None, torque_noise=0.0)}, environment_kwargs={"time_limit": 1.0})
        env.reset()
        theta = [env.step(u).observation["link_angle"][0] for u in acts]
        out[k1] = float(np.max(np.abs(np.array(theta) - ref)))
    out["swing"] = float(np.ptp(ref))
    return out


def import_times(repeats: int) -> np.ndarray:
    """(import mjjoint, then import mjjoint.control) [s] in a fresh interpreter, best of repeats."""
    code = ("import time; t0 = time.perf_counter(); import mjjoint; t1 = time.perf_counter(); "
            "import mjjoint.control; print(t1 - t0, time.perf_counter() - t1)")
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
            for _ in range(repeats)]
    return np.min(np.array(runs, dtype=float), axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    print("| arm | task | zero | pd | torque | env step [us] | bare 2 x mj_step [us] |")
    print("|---|---|---|---|---|---|---|")
    for model in MODELS:
        bare = min(bare_step(model) for _ in range(args.repeats)) * 1e6
        for task in TASKS:
            env = load(task, model, task_kwargs={"random": 0})
            zero = [run(env) for _ in range(args.repeats)]
            pd, torque = (run(load(task, model, task_kwargs={"random": 0}), p)[0] for p in (pd_policy, torque_policy))
            cost = min(z[1] for z in zero) * 1e6
            print(f"| {model} | {task} | {zero[0][0]:.3f} | {pd:.3f} | {torque:.3f} | {cost:.0f} | {bare:.0f} |")
    limit = rigid_limit()
    print(f"\nstiff joint vs rigid arm, max |theta - theta_rigid| over a {limit.pop('swing'):.2f} rad swing:")
    for k1, err in limit.items():
        print(f"  k1 = {k1:.0e} N m/rad: {err:.2e} rad")
    base, extra = import_times(args.repeats)
    print(f"\nimport mjjoint {base:.2f} s; then import mjjoint.control (dm_control) {extra:.2f} s more")


if __name__ == "__main__":
    main()
