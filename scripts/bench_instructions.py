"""Per-step cost of the joint physics as instructions inside ``mj_step``: deterministic, the primary figure.

Each pair steps a model with the joint physics (``with``) and the same MJCF without it
(``bare``: the plugin instances deleted, bodies, joints, rod springs and actuators kept) from
the same saved states: ``--steps`` steps of the ``with`` model's own run, cut into segments of
``--segment`` steps, each segment restarted from that run's state (time, qpos, qvel, act and
plugin states; the bare model takes time, qpos and qvel), with the same controls. So both sides
of a ratio compute the same motion and differ only in the joint physics.

  single joint     the shipped arm (build_arm defaults): the plugin, 2SEP + Bouc-Wen + load friction
  3-joint arm      mjjoint/assets/mjcf/arm3.xml: three plugin instances
  3-joint, 1 instance   the same arm with one plugin instance driving the three joints
  plugin floor     the shipped arm with the plugin at its least: a linear gear spring, no friction,
                   no hysteresis (MuJoCo's dispatch of one instance and the callback, nearly no physics)
  dcmotor anchor   the native reference: the single-joint bare arm whose motor actuator is
                   MuJoCo's C <dcmotor> with LuGre friction and cogging (scripts/bench_step.py)

Instructions are counted by valgrind's callgrind, collecting only inside ``mj_step``
(``--toggle-collect=mj_step``, callees such as the plugin's compute included); the script runs
itself under valgrind (``--worker``) and cuts the counts per configuration with a dump at each
call of ``mj_versionString``, a function the stepping never calls. The counts repeat to within
a few instructions a step from run to run, unlike times on a shared machine. The worker runs
without ``OPENBLAS_CORETYPE``: valgrind's emulated CPU lacks AVX-512, which a forced Skylake-X
OpenBLAS would execute. Wall time (this thread's CPU time, the same
rollouts natively, best of ``--repeats`` interleaved) is printed beside them.

    python scripts/bench_instructions.py            # needs valgrind on PATH (apt-get install valgrind)
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from bench_step import bare_spec, controls, dcmotor_model
from mujoco import rollout

from mjjoint.assets import ASSETS_DIR, build_arm, load_model
from mjjoint.assets.serial import build_serial_arm
from mjjoint.assets.shipped_arms import arm3
from mjjoint.joint import JointParams
from mjjoint.physics.transmission import Transmission

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
CARRIED = mujoco.mjtState.mjSTATE_TIME | mujoco.mjtState.mjSTATE_QPOS | mujoco.mjtState.mjSTATE_QVEL
STEPS, SEGMENT, REPEATS = 1000, 20, 7
ARM3 = Path(ASSETS_DIR) / "arm3.xml"
CASES = ("single joint", "3-joint arm", "3-joint, 1 instance", "plugin floor", "dcmotor anchor")
FLOOR = JointParams(friction=None, load_friction=None, transmission=Transmission(hysteresis=None, k3=0.0))
ORDER = [(name, side) for name in CASES for side in ("with", "bare")]  # the worker's dump order


def without_plugins(spec: mujoco.MjSpec) -> mujoco.MjSpec:
    for plugin in list(spec.plugins):
        spec.delete(plugin)
    return spec


def cases() -> dict[str, tuple[mujoco.MjModel, mujoco.MjModel]]:
    """name -> (model with the joint physics, the bare model), in ``CASES`` order."""
    bare = bare_spec().compile()
    arm3_bare = without_plugins(mujoco.MjSpec.from_file(str(ARM3))).compile()
    grouped = build_serial_arm(arm3(), one_instance=True)
    grouped_bare = without_plugins(build_serial_arm(arm3(), one_instance=True)).compile()
    pairs = ((load_model(build_arm()), bare), (load_model(ARM3), arm3_bare), (load_model(grouped), grouped_bare),
             (load_model(build_arm(joint=FLOOR)), bare), (dcmotor_model(), bare))
    return dict(zip(CASES, pairs))


class Segments:
    """Rollouts of one model from states along a reference model's own run (single thread)."""

    def __init__(self, model: mujoco.MjModel, reference: mujoco.MjModel, steps: int, segment: int):
        ctrl = controls(reference, steps)
        ref_data = mujoco.MjData(reference)
        x0 = np.empty((1, mujoco.mj_stateSize(reference, FULL)))
        mujoco.mj_getState(reference, ref_data, x0[0], FULL)
        run, _ = rollout.rollout(reference, ref_data, x0, ctrl[None])
        starts = np.concatenate([x0, run[0, segment - 1:steps - 1:segment]])
        self.model, self.data, self.segment = model, mujoco.MjData(model), segment
        self.x0 = np.empty((len(starts), mujoco.mj_stateSize(model, FULL)))
        part = np.empty(mujoco.mj_stateSize(reference, CARRIED))
        for i, x in enumerate(starts):
            if model is reference:
                self.x0[i] = x
                continue
            mujoco.mj_setState(reference, ref_data, x, FULL)
            mujoco.mj_getState(reference, ref_data, part, CARRIED)
            mujoco.mj_resetData(model, self.data)
            mujoco.mj_setState(model, self.data, part, CARRIED)
            mujoco.mj_getState(model, self.data, self.x0[i], FULL)
        self.ctrl = ctrl[:len(starts) * segment].reshape(len(starts), segment, -1)
        self.state = np.empty((len(starts), segment, self.x0.shape[1]))
        self.sensor = np.empty((len(starts), segment, model.nsensordata))
        self.steps = len(starts) * segment

    def run(self) -> None:
        rollout.rollout([self.model] * len(self.x0), [self.data], self.x0, self.ctrl, skip_checks=True,
                        nstep=self.segment, state=self.state, sensordata=self.sensor)

    def seconds(self) -> float:
        t = time.thread_time()
        self.run()
        return time.thread_time() - t


def configurations(steps: int, segment: int) -> dict[tuple[str, str], Segments]:
    """(case, "with" | "bare") -> Segments, in ``ORDER``."""
    out = {}
    for name, (model, bare) in cases().items():
        out[(name, "with")] = Segments(model, model, steps, segment)
        out[(name, "bare")] = Segments(bare, model, steps, segment)
    assert list(out) == ORDER
    return out


def worker(steps: int, segment: int) -> None:
    """Under callgrind: each configuration once, a dump (mj_versionString) before and after each."""
    configs = configurations(steps, segment)
    for s in configs.values():
        mujoco.mj_versionString()
        s.run()
    mujoco.mj_versionString()


def count_instructions(steps: int, segment: int, keep: Path | None) -> list[int]:
    """Instructions inside mj_step for each configuration, in ``configurations`` order."""
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        sys.exit("valgrind not found on PATH (apt-get install valgrind)")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(keep or tmp)
        out.mkdir(parents=True, exist_ok=True)
        cmd = [valgrind, "--tool=callgrind", "--toggle-collect=mj_step", "--dump-before=mj_versionString",
               f"--callgrind-out-file={out / 'callgrind.out'}", sys.executable, __file__, "--worker",
               "--steps", str(steps), "--segment", str(segment)]
        env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
        done = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if done.returncode != 0:
            sys.exit(f"callgrind run failed ({done.returncode}):\n{done.stderr[-3000:]}")
        parts = {}
        for f in out.glob("callgrind.out.*"):
            text = f.read_text(errors="replace")
            if "Trigger: --dump-before=mj_versionString" in text:
                part = int(re.search(r"^part: (\d+)", text, re.M).group(1))
                parts[part] = int(re.search(r"^totals: (\d+)", text, re.M).group(1))
    # The worker's markers make the last len(ORDER) + 1 dumps; the first of them closes the set-up.
    counts = [parts[p] for p in sorted(parts)][-(len(ORDER) + 1):]
    return counts[1:]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=STEPS, help=f"steps per configuration (default {STEPS})")
    ap.add_argument("--segment", type=int, default=SEGMENT, help=f"steps per restarted segment (default {SEGMENT})")
    ap.add_argument("--repeats", type=int, default=REPEATS, help=f"timed runs, best counts (default {REPEATS})")
    ap.add_argument("--keep", type=Path, help="keep the callgrind dumps in this folder")
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.steps, args.segment)
        return

    configs = configurations(args.steps, args.segment)
    for s in configs.values():  # warm-up: numba caches, page faults
        s.run()
    best = {k: float("inf") for k in configs}
    for _ in range(args.repeats):
        for k, s in configs.items():
            best[k] = min(best[k], s.seconds())
    steps = next(iter(configs.values())).steps
    us = {k: v / steps * 1e6 for k, v in best.items()}
    ir = dict(zip(configs, (c / steps for c in count_instructions(args.steps, args.segment, args.keep))))

    print(f"mujoco {mujoco.__version__}; {steps} steps per configuration ({steps // args.segment} segments of "
          f"{args.segment}) from the same states; instructions inside mj_step (callgrind), wall = thread "
          f"CPU time, best of {args.repeats}")
    width = max(map(len, CASES)) + 2
    print(f"{'case':<{width}}{'configuration':<15}{'instr/step':>12}{'us/step':>10}")
    for (name, side), v in ir.items():
        print(f"{name:<{width}}{side:<15}{v:>12.0f}{us[(name, side)]:>10.3f}")
    for name in dict.fromkeys(n for n, _ in configs):
        ratio = ir[(name, "with")] / ir[(name, "bare")]
        wall = us[(name, "with")] / us[(name, "bare")]
        print(f"{name}: with / bare = {ratio:.3f}x instructions  (wall {wall:.3f}x)")


if __name__ == "__main__":
    main()
