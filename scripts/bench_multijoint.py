"""Per-step cost of the joint plugin on the 3-DOF arm, against the same arm without it.

One process, single thread, the measurement of scripts/bench_step.py (its RolloutTimer and
StepLoopTimer: thread CPU time, configurations interleaved per repeat, best repeat counts):
  arm3 plugin   mjjoint/assets/mjcf/arm3.xml: three mjjoint.joint instances (full nonlinear physics)
  arm3 bare     the same MJCF with the plugin instances deleted (bodies, rods, actuators kept)
  single ...    the shipped single-joint arm, plugin and bare, from the same run
Timers as in bench_step; "state-matched" (both arms rolled out from the same states along the
plugin run, see bench_step) is the one that isolates the plugin's cost.
The plugin's cost per joint instance is (plugin - bare) / njoint; the ratio plugin / bare
shrinks with the arm's size when that cost stays flat, since MuJoCo's own work grows faster.

    python scripts/bench_multijoint.py --steps 20000 --repeats 7
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import mujoco

sys.path.insert(0, str(Path(__file__).resolve().parent))  # scripts/ is not a package
from bench_step import (  # the shared measurement
    SEGMENT,
    RolloutTimer,
    StepLoopTimer,
    bare_spec,
    best_us_per_step,
    state_matched,
)

from mjjoint.assets import build_arm, load_model
from mjjoint.assets.builder import ASSETS_DIR


def without_plugins(path: Path) -> mujoco.MjModel:
    spec = mujoco.MjSpec.from_file(str(path))
    for plugin in list(spec.plugins):
        spec.delete(plugin)
    return spec.compile()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=20000, help="steps per timed run (default 20000 = 10 s)")
    ap.add_argument("--repeats", type=int, default=7, help="timed runs per configuration; the best counts")
    args = ap.parse_args()

    models = {
        "single": (load_model(build_arm()), bare_spec().compile()),
        "arm3": (load_model(ASSETS_DIR / "arm3.xml"), without_plugins(ASSETS_DIR / "arm3.xml")),
    }
    for plugin, bare in models.values():
        assert bare.nplugin == 0 and (plugin.nq, plugin.nu) == (bare.nq, bare.nu)
    timers = {}
    for arm, (plugin, bare) in models.items():
        for kind, model in (("plugin", plugin), ("bare", bare)):
            timers[("rollout", arm, kind)] = RolloutTimer(model, args.steps)
            timers[("mj_step loop", arm, kind)] = StepLoopTimer(model, args.steps)
        matched = state_matched({"plugin": plugin, "bare": bare}, plugin, args.steps, SEGMENT)
        timers.update({("state-matched", arm, kind): t for kind, t in matched.items()})
    us = best_us_per_step(timers, args.steps, args.repeats)

    print(f"mujoco {mujoco.__version__}; {args.steps} steps of {models['arm3'][0].opt.timestep * 1e3:g} ms, "
          f"best of {args.repeats}, single thread")
    print(f"{'timer':<14}{'arm':<8}{'nv':>4}{'joints':>8}{'plugin us':>11}{'bare us':>9}{'ratio':>8}{'us/joint':>10}")
    for timer in ("state-matched", "rollout", "mj_step loop"):
        for arm, (plugin, _) in models.items():
            p, b = us[(timer, arm, "plugin")], us[(timer, arm, "bare")]
            print(f"{timer:<14}{arm:<8}{plugin.nv:>4}{plugin.nplugin:>8}{p:>11.3f}{b:>9.3f}{p / b:>8.3f}"
                  f"{(p - b) / plugin.nplugin:>10.3f}")
    for timer in ("state-matched", "rollout", "mj_step loop"):
        r3 = us[(timer, "arm3", "plugin")] / us[(timer, "arm3", "bare")]
        r1 = us[(timer, "single", "plugin")] / us[(timer, "single", "bare")]
        print(f"plugin / bare, {timer}: arm3 {r3:.3f}x vs single joint {r1:.3f}x")


if __name__ == "__main__":
    main()
