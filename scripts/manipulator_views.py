"""Held-out NRMSE of each joint's single-joint view at the true values, no fit: alone, with the
other joints' measured motion as a load through the arm (``--arm``, ``mjjoint.manipulator``),
and alone on a recording where the other joints are locked (where the view is exact for rigid
links: the windows' own error). Arms: the test arm of tests/test_multijoint_diagnose.py (yaw +
pitch, and turned planar), the shipped arm3's bodies with rigid rods, and arm3 as shipped
(flexible rods). Every joint tracks the tests' three sines (0.7-5.3 Hz, 0.2 rad p-p) for 3 s
under a motor-side PD; 0.1 s windows.

    python scripts/manipulator_views.py            # ~1 min on 2 cores
"""
from __future__ import annotations

import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the tests' arm, references and lock
from test_manipulator import PLANAR_TOML  # noqa: E402
from test_multijoint import lock  # noqa: E402
from test_multijoint_diagnose import ARM_TOML, references  # noqa: E402

from mjjoint.assets import load_model  # noqa: E402
from mjjoint.assets.serial import build_serial_arm  # noqa: E402
from mjjoint.assets.serial_file import SerialArmFile, parse_serial_arm  # noqa: E402
from mjjoint.assets.shipped_arms import arm3  # noqa: E402
from mjjoint.identify.fit import evaluate  # noqa: E402
from mjjoint.identify.windows import Measured, Predictor, WindowDesign  # noqa: E402
from mjjoint.problem import Inputs, load_problem  # noqa: E402
from mjjoint.sim import Simulator  # noqa: E402
from mjjoint.trace_recording import recording  # noqa: E402
from mjjoint.tracking import track  # noqa: E402

DESIGN = WindowDesign(length=0.1)


def _toml(text: str) -> SerialArmFile:
    import tomllib
    return parse_serial_arm(tomllib.loads(text))


def _run(model, n: int, moving=None):
    kp = [0.1] + [0.2] * (n - 1)
    return recording(track(Simulator(model), references(n, moving), kp=kp, kd=0.004))


def _nrmse(predictor, structure) -> str:
    r = evaluate(predictor, structure)[3]
    return " / ".join(f"{r[s]:.3f}" for s in ("q", "delta", "tau"))


def main() -> None:
    arms = {
        "test arm, orthogonal axes": _toml(ARM_TOML),
        "test arm, parallel axes": _toml(PLANAR_TOML),
        "arm3 bodies, rigid rods": SerialArmFile(tuple(dataclasses.replace(js, segments=0) for js in arm3())),
        "arm3 as shipped (flexible rods)": SerialArmFile(tuple(arm3())),
    }
    print("| arm | joint | alone: q / delta / tau | with --arm | alone, others locked | load [s] |")
    print("|---|---|---|---|---|---|")
    for name, arm in arms.items():
        n = len(arm.joints)
        rec = _run(arm.compile(), n)
        for j in range(1, n + 1):
            spec = build_serial_arm(list(arm.joints), arm.world)
            for k in set(range(1, n + 1)) - {j}:
                lock(spec, f"motor{k}", f"link{k}")
            still = _run(load_model(spec), n, moving=[j - 1]).joint(j)
            alone = load_problem(rec, Inputs(model=arm, joints=(j,), design=DESIGN)).problems[j]
            start = time.perf_counter()
            loaded = load_problem(rec, Inputs(model=arm, joints=(j,), design=DESIGN, arm=arm)).problems[j]
            seconds = time.perf_counter() - start
            floor = Predictor(Measured.from_recording(still, alone.base.gear_ratio), DESIGN)
            print(f"| {name} | {j} | {_nrmse(alone.predictor, alone.base)} | {_nrmse(loaded.predictor, loaded.base)} "
                  f"| {_nrmse(floor, alone.base)} | {seconds:.2f} |")


if __name__ == "__main__":
    main()
