"""Held-out NRMSE of each joint at the true values, no fit: its single-joint view alone; inside
the whole arm with the other joints following their measured motion (``--arm`` with a
[[joint]] file); its view with the load of that motion (``--arm`` with an MJCF); and its view
alone on a recording where the other joints are locked (exact for rigid links: the windows'
own error). Arms: the test arm of tests/test_multijoint_diagnose.py (yaw +
pitch, and turned planar), the shipped arm3's bodies with rigid rods, and arm3 as shipped
(flexible rods). Every joint tracks the tests' three sines (0.7-5.3 Hz, 0.2 rad p-p) for 3 s
under a motor-side PD; 0.1 s windows.

    python scripts/manipulator_views.py            # ~1 min on 2 cores
"""
from __future__ import annotations

import dataclasses
import sys
import tempfile
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
    print("| arm | joint | alone: q / delta / tau | inside the arm ([[joint]] file) | load (MJCF) "
          "| alone, others locked | s: alone / inside / load |")
    print("|---|---|---|---|---|---|---|")
    for name, arm in arms.items():
        n = len(arm.joints)
        rec = _run(arm.compile(), n)
        xml = Path(tempfile.mkdtemp()) / "arm.xml"
        xml.write_text(build_serial_arm(list(arm.joints), arm.world).to_xml())
        for j in range(1, n + 1):
            spec = build_serial_arm(list(arm.joints), arm.world)
            for k in set(range(1, n + 1)) - {j}:
                lock(spec, f"motor{k}", f"link{k}")
            still = _run(load_model(spec), n, moving=[j - 1]).joint(j)
            cells, seconds = [], []
            for given in (None, arm, xml):  # problem + one prediction of every window, timed
                start = time.perf_counter()
                p = load_problem(rec, Inputs(model=arm, joints=(j,), design=DESIGN, arm=given)).problems[j]
                cells.append(_nrmse(p.predictor, p.base))
                seconds.append(f"{time.perf_counter() - start:.2f}")
            floor = Predictor(Measured.from_recording(still, p.base.gear_ratio), DESIGN)
            print(f"| {name} | {j} | {' | '.join(cells)} | {_nrmse(floor, p.base)} | {' / '.join(seconds)} |")


if __name__ == "__main__":
    main()
