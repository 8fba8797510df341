"""Per-step cost of the joint physics: the compiled plugin against a bare arm and the alternatives.

One process, single thread. Each configuration is the shipped arm (build_arm defaults):
  bare      the same MJCF with the mjjoint.joint plugin instance deleted (bodies, joints,
            rod springs and actuator kept): the floor every variant is compared with;
  plugin    the full nonlinear joint: 2SEP + Bouc-Wen transmission + load friction;
  spring    the plugin with a linear spring only (every other term off): the cost of the
            plugin mechanism (one numba callback per step) apart from the physics;
  dcmotor   no plugin, MuJoCo's native <dcmotor> on the motor joint with LuGre friction and
            cogging (mujoco >= 3.17), sized like the plugin's defaults;
  callback  no plugin, the same physics from Python: mjcb_passive calls the numba kernels
            (joint_catch_up + joint_forces, as the plugin's compute), with the internal states
            in a Python-held array: what the plugin replaces;
  kernels   the plugin's physics alone (joint_catch_up + joint_forces in a compiled loop over
            the plugin run's own trajectory), no MuJoCo: the part of the overhead that is
            physics rather than mechanism, as a share of the bare step.
Three timers: mujoco.rollout (single thread, outputs preallocated), a Python loop of mj_step
(the callback can only run there), and state-matched rollouts. Without the plugin the link is
not coupled to the motor and hangs still, and MuJoCo's own step costs less at rest than along
a swinging trajectory (the "bare along the trajectory" line shows by how much). So the
state-matched timer rolls out every configuration from the same states, taken every
``--segment`` steps along the plugin run's trajectory, for ``--segment`` steps each: the same
MJCF and the same motion with and without the plugin, which isolates what the plugin costs.
Times are this thread's CPU time, so other processes on a shared machine do not count; every
repeat re-runs all configurations in turn (interleaved, so cache and frequency drifts hit all
alike) and the best repeat counts.

    python scripts/bench_step.py --steps 20000 --repeats 7

These are times; the deterministic per-step figure (instructions inside mj_step, the same
states with and without the plugin) is scripts/bench_instructions.py.
"""
from __future__ import annotations

import argparse
import time

import mujoco
import numpy as np
from mujoco import rollout
from numba import njit

from mjjoint.assets import ArmSpec, build_arm, load_model
from mjjoint.coupling.kernels import joint_catch_up, joint_forces
from mjjoint.coupling.layout import AT, NSTATE, pack
from mjjoint.joint import JointParams
from mjjoint.physics.ripple import TorqueRipple
from mjjoint.physics.transmission import Transmission
from mjjoint.physics.twosep import TwoSEP
from mjjoint.sim import joint_indices

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
TARGET = 1.05  # plugin / bare, compiled path
SEGMENT = 20  # steps per state-matched rollout: 10 ms, too short for the bare arm to drift off


def bare_spec() -> mujoco.MjSpec:
    spec = build_arm()
    for plugin in list(spec.plugins):
        spec.delete(plugin)
    return spec


def dcmotor_model() -> mujoco.MjModel:
    """Bare arm whose motor actuator is a dcmotor with LuGre friction and cogging."""
    spec = bare_spec()
    act = spec.actuator("current")
    f, r = TwoSEP(), TorqueRipple()
    act.gear[0] = 1.0  # the motor constant takes the role of the torque constant
    act.set_to_dcmotor(
        motorconst=[0.25, 0.25], resistance=1.0,
        cogging=[r.amplitude, r.harmonic, r.phase],
        # LuGre: bristle stiffness K Fc (2SEP's initial pre-sliding slope), bristle damping
        # ~critical on the rotor, Coulomb, stiction, Stribeck velocity.
        lugre=[f.k * f.fc, 2 * np.sqrt(f.k * f.fc * 5e-5), f.fc, f.fs, f.vs])
    act.damping[0] = f.sigma  # viscous part
    return spec.compile()


def controls(model: mujoco.MjModel, steps: int) -> np.ndarray:
    """0.5 (A or V) at 1 Hz: the arm swings, the friction reverses, nothing saturates."""
    t = np.arange(steps) * model.opt.timestep
    return np.repeat((0.5 * np.sin(2 * np.pi * t))[:, None], model.nu, axis=1)


def best_us_per_step(timers: dict, steps: int, repeats: int) -> dict:
    """Interleaved repeats after a warm-up (numba caches, pools, page faults); best of each, in us/step."""
    for t in timers.values():
        t()
    best = {k: float("inf") for k in timers}
    for _ in range(repeats):
        for k, t in timers.items():
            best[k] = min(best[k], t())
    return {k: v / steps * 1e6 for k, v in best.items()}


class RolloutTimer:
    def __init__(self, model: mujoco.MjModel, steps: int):
        self.model, self.data = model, mujoco.MjData(model)
        mujoco.mj_resetData(model, self.data)
        self.x0 = np.empty((1, mujoco.mj_stateSize(model, FULL)))
        mujoco.mj_getState(model, self.data, self.x0[0], FULL)
        self.ctrl = controls(model, steps)[None]
        self.state = np.empty((1, steps, self.x0.shape[1]))
        self.sensor = np.empty((1, steps, model.nsensordata))

    def __call__(self) -> float:
        t = time.thread_time()
        rollout.rollout([self.model], [self.data], self.x0, self.ctrl, skip_checks=True,
                        nstep=self.ctrl.shape[1], state=self.state, sensordata=self.sensor)
        return time.thread_time() - t


class MatchedTimer:
    """Rollouts of ``segment`` steps from states along a reference run, one batch in one thread.

    ``reference`` is a RolloutTimer that has run; its states (and controls) are restarted every
    ``segment`` steps. ``model`` may lack the reference's plugin: time, qpos, qvel and act carry
    over (deleting a plugin keeps them), plugin states where the model has them.
    """

    def __init__(self, model: mujoco.MjModel, reference: "RolloutTimer", segment: int):
        ref = reference.model
        assert (model.nq, model.nv, model.na, model.nu) == (ref.nq, ref.nv, ref.na, ref.nu)
        steps = reference.ctrl.shape[1] // segment * segment
        starts = np.concatenate([reference.x0, reference.state[0, segment - 1:steps - 1:segment]])
        self.model, self.data, self.segment = model, mujoco.MjData(model), segment
        src, dst = mujoco.MjData(ref), self.data
        self.x0 = np.empty((len(starts), mujoco.mj_stateSize(model, FULL)))
        for i, x in enumerate(starts):
            mujoco.mj_setState(ref, src, x, FULL)
            dst.time, dst.qpos[:], dst.qvel[:], dst.act[:] = src.time, src.qpos, src.qvel, src.act
            if model.nplugin:
                dst.plugin_state[:] = src.plugin_state
            mujoco.mj_getState(model, dst, self.x0[i], FULL)
        self.ctrl = reference.ctrl[0, :steps].reshape(len(starts), segment, -1)
        self.state = np.empty((len(starts), segment, self.x0.shape[1]))
        self.sensor = np.empty((len(starts), segment, model.nsensordata))

    def __call__(self) -> float:
        t = time.thread_time()
        rollout.rollout([self.model] * len(self.x0), [self.data], self.x0, self.ctrl, skip_checks=True,
                        nstep=self.segment, state=self.state, sensordata=self.sensor)
        return time.thread_time() - t


def state_matched(models: dict, reference: mujoco.MjModel, steps: int, segment: int) -> dict:
    """MatchedTimers of ``models`` (name -> model) along ``reference``'s own rollout."""
    run = RolloutTimer(reference, steps)
    run()
    return {name: MatchedTimer(m, run, segment) for name, m in models.items()}


class StepLoopTimer:
    """mj_step in a Python loop; with ``callback``, the joint physics run from Python."""

    def __init__(self, model: mujoco.MjModel, steps: int, callback: bool = False):
        self.model, self.data = model, mujoco.MjData(model)
        self.ctrl = controls(model, steps)
        self.callback = callback
        if callback:
            motor, link = model.joint("motor"), model.joint("link")
            self.mq, self.md = int(motor.qposadr[0]), int(motor.dofadr[0])
            self.lq, self.ld = int(link.qposadr[0]), int(link.dofadr[0])
            self.block = pack(JointParams(), self.mq, self.md, self.lq, self.ld)
            self.st = np.zeros(NSTATE)
            self.hj = tuple(float(model.opt.timestep * model.dof_invweight0[i]) for i in (self.md, self.ld))

    def passive(self, m, d) -> None:
        args = (self.block, self.st, d.qpos[self.mq], d.qvel[self.md], d.qpos[self.lq], d.qvel[self.ld])
        joint_catch_up(*args, d.time, m.opt.timestep, *self.hj)
        fm, fl = joint_forces(*args, m.opt.timestep, *self.hj)
        d.qfrc_passive[self.md] += fm
        d.qfrc_passive[self.ld] += fl

    def run(self) -> np.ndarray:
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        if not self.callback:
            for c in self.ctrl:
                d.ctrl[:] = c
                mujoco.mj_step(m, d)
            return d.qpos.copy()
        self.st[:] = 0.0
        self.st[AT] = np.nan  # fresh, as after a reset
        mujoco.set_mjcb_passive(self.passive)
        try:
            for c in self.ctrl:
                d.ctrl[:] = c
                mujoco.mj_step(m, d)
        finally:
            mujoco.set_mjcb_passive(None)
        return d.qpos.copy()

    def __call__(self) -> float:
        t = time.thread_time()
        self.run()
        return time.thread_time() - t


@njit(cache=True)
def _replay(blk, st, q, wq, theta, wtheta, h, hj, hjl):
    acc = 0.0
    for i in range(q.shape[0]):
        joint_catch_up(blk, st, q[i], wq[i], theta[i], wtheta[i], i * h, h, hj, hjl)
        fm, fl = joint_forces(blk, st, q[i], wq[i], theta[i], wtheta[i], h, hj, hjl)
        acc += fm + fl
    return acc


class KernelTimer:
    """The plugin's physics kernels over the plugin model's own trajectory, without MuJoCo."""

    def __init__(self, model: mujoco.MjModel, steps: int):
        ji = joint_indices(model)[0]
        timer = RolloutTimer(model, steps)
        timer()
        nq = model.nq
        s = timer.state[0]
        self.args = (ji.block, np.zeros(NSTATE), s[:, 1 + ji.motor_qpos].copy(), s[:, 1 + nq + ji.motor_dof].copy(),
                     s[:, 1 + ji.link_qpos].copy(), s[:, 1 + nq + ji.link_dof].copy(),
                     *ji.steps(model))

    def __call__(self) -> float:
        self.args[1][:] = 0.0
        self.args[1][AT] = np.nan
        t = time.thread_time()
        _replay(*self.args)
        return time.thread_time() - t


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000, help="steps per timed run (default 20000 = 10 s)")
    ap.add_argument("--repeats", type=int, default=7, help="timed runs per configuration; the best counts")
    ap.add_argument("--segment", type=int, default=SEGMENT,
                    help=f"steps per state-matched rollout (default {SEGMENT})")
    args = ap.parse_args()

    plugin, bare, dc = load_model(build_arm()), bare_spec().compile(), dcmotor_model()
    spring = load_model(build_arm(ArmSpec(), JointParams(
        friction=None, load_friction=None, transmission=Transmission(hysteresis=None, damping=0.0))))
    assert plugin.nplugin == 1 and bare.nplugin == 0 and dc.nplugin == 0
    assert dc.actuator_dyntype[0] == mujoco.mjtDyn.mjDYN_DCMOTOR and dc.na == 1  # LuGre bristle state
    timers = {
        ("rollout", "bare"): RolloutTimer(bare, args.steps),
        ("rollout", "plugin"): RolloutTimer(plugin, args.steps),
        ("rollout", "spring"): RolloutTimer(spring, args.steps),
        ("rollout", "dcmotor"): RolloutTimer(dc, args.steps),
        ("mj_step loop", "bare"): StepLoopTimer(bare, args.steps),
        ("mj_step loop", "plugin"): StepLoopTimer(plugin, args.steps),
        ("mj_step loop", "callback"): StepLoopTimer(bare, args.steps, callback=True),
        ("kernels", "physics"): KernelTimer(plugin, args.steps),
    }
    matched = state_matched({"bare": bare, "plugin": plugin, "spring": spring}, plugin, args.steps, args.segment)
    timers.update({("state-matched", name): t for name, t in matched.items()})
    us = best_us_per_step(timers, args.steps, args.repeats)

    # The Python path must be the same physics as the plugin, or the comparison means nothing.
    same = np.max(np.abs(timers[("mj_step loop", "plugin")].run() - timers[("mj_step loop", "callback")].run()))

    print(f"mujoco {mujoco.__version__}; {args.steps} steps of {plugin.opt.timestep * 1e3:g} ms, "
          f"best of {args.repeats}, single thread")
    print(f"{'timer':<14}{'configuration':<12}{'us/step':>10}{'/ bare':>10}")
    for (timer, name), v in us.items():
        share = v / us[(timer if timer != "kernels" else "state-matched", "bare")]
        print(f"{timer:<14}{name:<12}{v:>10.3f}{share:>10.3f}")
    print(f"callback path reproduces the plugin: max |qpos difference| after {args.steps} steps = {same:.1e}")
    for timer in ("state-matched", "rollout", "mj_step loop"):
        ratio = us[(timer, "plugin")] / us[(timer, "bare")]
        verdict = "met" if ratio <= TARGET else "NOT met"
        print(f"(a) plugin / bare, {timer}: {ratio:.3f}x  (target <= {TARGET}x: {verdict})")
    print(f"    bare along the plugin's trajectory / bare from rest: "
          f"{us[('state-matched', 'bare')] / us[('rollout', 'bare')]:.3f}x (MuJoCo's own cost of the motion)")
    print(f"(b) dcmotor+LuGre+cogging / bare, rollout: {us[('rollout', 'dcmotor')] / us[('rollout', 'bare')]:.3f}x")
    physics = us[("kernels", "physics")] / us[("state-matched", "bare")]
    mechanism = us[("state-matched", "spring")] / us[("state-matched", "bare")] - 1
    print(f"    of which physics kernels alone: {physics:.3f} of a bare step; plugin mechanism with a "
          f"linear spring: {mechanism:.3f}")
    print(f"(c) Python callback / bare, mj_step loop: "
          f"{us[('mj_step loop', 'callback')] / us[('mj_step loop', 'bare')]:.3f}x  "
          f"(plugin: {us[('mj_step loop', 'plugin')] / us[('mj_step loop', 'bare')]:.3f}x)")


if __name__ == "__main__":
    main()
