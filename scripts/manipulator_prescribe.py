"""Ways to make the other joints of an arm follow their recorded motion, compared on joint j.

The parallel-axes test arm (tests/test_manipulator.py), both joints tracking three sines for 3 s.
Joint j is replayed open loop under its recorded motor torque for the whole recording from the
recorded start (home, at rest), the other joint made to follow its recording by:
  alone       nothing: joint j's single-joint view (the per-joint CLI without --arm)
  load        the view with the load of the others' measured motion (``--arm``, mjjoint.manipulator)
  kinematic   the whole arm, the other joint's qpos and qvel set to the recording every step
  servo F     the whole arm, the other joint's motor and link held by position + velocity servos
              on the recording, bandwidth F Hz (critically damped on each dof's own inertia)
  exact       the whole arm, the other joint's qpos and qvel set every step and its acceleration
              imposed: the generalised force on its dofs that gives the measured acceleration
              (Schur complement of MuJoCo's mass matrix), a Python step per substep
  heavy       the whole arm, the other joint's dofs given an armature of 1e6 kg m^2 and pushed by
              1e6 x their measured acceleration, with a 1 Hz correction onto their measured angle
              (``--arm`` with a [[joint]] file: mjjoint.manipulator.whole; here stepped in Python)
  ... (other's k1 x0.5): the same with the other joint's gear stiffness halved in the arm model,
              as when its model is not known: what the method takes from the other joint's model
The same for the shipped arm3 (flexible rods; the other joints' rods simulated in every
whole-arm method, at rest in the load).
Printed: RMSE of joint j's q, theta and delta over the run, each over the signal's rms spread,
and the wall time (2 shared cores).

    python scripts/manipulator_prescribe.py
"""
from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' arm and references
from test_manipulator import PLANAR_TOML  # noqa: E402
from test_multijoint_diagnose import references  # noqa: E402

from mjjoint.assets.serial import build_serial_arm  # noqa: E402
from mjjoint.assets.serial_file import SerialArmFile, parse_serial_arm  # noqa: E402
from mjjoint.assets.shipped_arms import arm3  # noqa: E402
from mjjoint.coupling.mjlog import mujoco_log_silenced  # noqa: E402
from mjjoint.manipulator.whole import FOLLOW_HZ, _heavy_arm  # noqa: E402
from mjjoint.sim import Simulator  # noqa: E402
from mjjoint.tracking import track  # noqa: E402
from mjjoint.assets import load_model  # noqa: E402
from mjjoint.manipulator.load import measured_motion  # noqa: E402
from mjjoint.problem import Inputs, load_problem  # noqa: E402
from mjjoint.sim import joint_indices  # noqa: E402
from mjjoint.trace_recording import recording  # noqa: E402


def _score(rec_j, q, theta) -> str:
    n = rec_j.gear_ratio
    pairs = ((rec_j.q, q), (rec_j.theta, theta), (rec_j.q / n - rec_j.theta, q / n - theta))
    return " / ".join(f"{np.sqrt(np.mean((b - a) ** 2)) / np.std(a):.3f}" for a, b in pairs)


def _whole_arm(model, rec, j: int, method: str, servo_hz: float = 0.0):
    """Joint j replayed in the whole arm, the others following the recording by ``method``."""
    ji = joint_indices(model)
    grid, motion = measured_motion(rec)
    h = model.opt.timestep
    sub = int(round(rec.dt / h))
    others = [k for k in range(len(ji)) if k != j - 1]
    dofs = [(ji[k].motor_qpos, ji[k].motor_dof, motion[k][:3]) for k in others] + \
           [(ji[k].link_qpos, ji[k].link_dof, motion[k][3:]) for k in others]
    names = [f"motor{k + 1}" for k in others] + [f"link{k + 1}" for k in others]
    d = mujoco.MjData(model)
    mujoco.mj_resetData(model, d)
    u = rec.joint(j).u / ji[j - 1].k_m
    kdof = np.array([v for _, v, _ in dofs])
    out_q, out_th = np.empty(rec.n), np.empty(rec.n)
    servo = None
    if method == "servo":
        w = 2 * np.pi * servo_hz
        inertia = 1.0 / model.dof_invweight0[kdof]
        servo = (inertia * w * w, 2 * inertia * w)
    for i in range(rec.n):
        out_q[i], out_th[i] = d.qpos[ji[j - 1].motor_qpos], d.qpos[ji[j - 1].link_qpos]
        for s in range(sub):
            t = i + s / sub
            ref = [(a, v, [np.interp(t, np.arange(rec.n), x) for x in xs]) for a, v, xs in dofs]
            d.ctrl[:] = 0.0
            d.ctrl[ji[j - 1].actuator] = u[i]
            d.qfrc_applied[:] = 0.0
            if method in ("kinematic", "exact"):
                for a, v, (p, pd, _) in ref:
                    d.qpos[a], d.qvel[v] = p, pd
            if method == "servo":
                err = np.array([p - d.qpos[a] for a, _, (p, _, _) in ref])
                derr = np.array([pd - d.qvel[v] for _, v, (_, pd, _) in ref])
                d.qfrc_applied[kdof] = servo[0] * err + servo[1] * derr
            if method == "heavy":  # the follower actuators' command (mjjoint.manipulator.whole)
                w = 2 * np.pi * FOLLOW_HZ
                for (_, v, (p, pd, pdd)), name in zip(ref, names):
                    d.ctrl[model.actuator(f"follow_{name}").id] = pdd + w * w * p + 2 * w * pd
            if method == "exact":
                mujoco.mj_step1(model, d)
                mujoco.mj_fwdActuation(model, d)
                free = d.qfrc_actuator + d.qfrc_passive - d.qfrc_bias
                minv = np.empty((model.nv, model.nv))
                mujoco.mj_solveM(model, d, minv, np.eye(model.nv))
                qacc0 = minv @ free
                want = np.array([pdd for _, _, (_, _, pdd) in ref])
                g = np.linalg.solve(minv[np.ix_(kdof, kdof)], want - qacc0[kdof])
                d.qfrc_applied[kdof] = g
                mujoco.mj_step2(model, d)
            else:
                mujoco.mj_step(model, d)
    return out_q, out_th


def _softer(arm, j: int):
    """``arm`` with every joint but j given half its gear stiffness."""
    joints = [js if k == j else dataclasses.replace(js, joint=dataclasses.replace(
        js.joint, transmission=dataclasses.replace(js.joint.transmission, k1=0.5 * js.joint.transmission.k1)))
        for k, js in enumerate(arm.joints, start=1)]
    return dataclasses.replace(arm, joints=tuple(joints))


def main() -> None:
    planar = parse_serial_arm(__import__("tomllib").loads(PLANAR_TOML))
    print("| arm | joint | method | q / theta / delta (RMSE over spread) | seconds |")
    print("|---|---|---|---|---|")
    for name, arm in (("test arm, parallel axes", planar), ("arm3 as shipped", SerialArmFile(tuple(arm3())))):
        n = len(arm.joints)
        rec = recording(track(Simulator(arm.compile()), references(n), kp=[0.1] + [0.2] * (n - 1), kd=0.004))
        for j in range(1, n + 1):
            xml = Path(tempfile.mkdtemp()) / "arm.xml"  # an MJCF arm takes the load route
            xml.write_text(build_serial_arm(list(arm.joints), arm.world).to_xml())
            for label, inputs in (("alone", Inputs(model=arm, joints=(j,))),
                                  ("load", Inputs(model=arm, joints=(j,), arm=xml))):
                start = time.perf_counter()
                p = load_problem(rec, inputs).problems[j]
                run = p.predictor.free_run(p.base)
                print(f"| {name} | {j} | {label} | {_score(rec.joint(j), run['q'], run['theta'])} "
                      f"| {time.perf_counter() - start:.1f} |")
            methods = [("kinematic", 0, arm), ("servo", 50.0, arm), ("servo", 200.0, arm), ("exact", 0, arm),
                       ("heavy", 0, arm), ("kinematic", 0, _softer(arm, j)), ("exact", 0, _softer(arm, j)),
                       ("heavy", 0, _softer(arm, j))]
            for method, hz, model in methods:
                start = time.perf_counter()
                compiled = (_heavy_arm(model, j) if method == "heavy"
                            else load_model(build_serial_arm(list(model.joints), model.world)))
                with mujoco_log_silenced():
                    q, th = _whole_arm(compiled, rec, j, method, hz)
                label = (f"servo {hz:g} Hz" if method == "servo" else method) + (" (other's k1 x0.5)" if model is not arm else "")
                print(f"| {name} | {j} | {label} | {_score(rec.joint(j), q, th)} | {time.perf_counter() - start:.1f} |")


if __name__ == "__main__":
    main()
