"""Every shipped MJCF scene and the arm's variants survive 2 s of random motor torque.

"Survive" means MuJoCo raised no warning of any kind (instability resets, bad controls,
full buffers, ...) and no state (qpos, qvel, act, plugin states) ever became NaN or inf.
Assets are discovered with a glob, so models added to mjjoint/assets/mjcf/ later are covered; a
file that does not compile on its own is skipped only when another asset includes it.
"""
from __future__ import annotations

import re

import mujoco
import numpy as np
import pytest
from scipy import signal

from mjjoint.assets import ArmSpec, build_arm, load_model
from mjjoint.assets.builder import ASSETS_DIR
from mjjoint.joint import JointParams
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.physics.transmission import Transmission
from mjjoint.physics.twosep import TwoSEP

DURATION = 2.0
INPUT_RATE = 1000.0  # the recordings' rate: torque held for 1 ms
BANDWIDTH = 20.0     # [Hz]: swings the link (~1 Hz) and reaches the rod's first mode (~21 Hz)
RELATIVE_AMPLITUDE = 0.05  # RMS, of each actuator's range: 1 A = 0.25 N m on the arm, twice the
                           # break-away friction and ~10x the largest gravity torque at the motor


def random_controls(model: mujoco.MjModel, seed: int) -> np.ndarray:
    """(steps, nu) band-limited noise: 20 Hz low-passed, RMS 5 % of each range, clipped to it."""
    rng = np.random.default_rng(seed)
    n = int(DURATION * INPUT_RATE)
    hold = round(1.0 / (INPUT_RATE * model.opt.timestep))
    if model.nu == 0:  # a passive scene: it still has to run
        return np.zeros((n * max(hold, 1), 0))
    sos = signal.butter(4, BANDWIDTH, fs=INPUT_RATE, output="sos")
    noise = signal.sosfiltfilt(sos, rng.standard_normal((n, model.nu)), axis=0)
    noise /= noise.std(axis=0)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    limited = model.actuator_ctrllimited.astype(bool)
    half = np.where(limited, (hi - lo) / 2, 1.0)
    centre = np.where(limited, (hi + lo) / 2, 0.0)
    u = centre + RELATIVE_AMPLITUDE * half * noise
    u = np.where(limited, np.clip(u, lo, hi), u)
    return np.repeat(u, max(hold, 1), axis=0)


def rollout_problems(model: mujoco.MjModel, ctrl: np.ndarray) -> list[str]:
    """Step the model through ``ctrl`` with mj_step; the warnings and non-finite states seen."""
    d = mujoco.MjData(model)
    problems = []
    for i, c in enumerate(ctrl):
        d.ctrl[:] = c
        mujoco.mj_step(model, d)
        for name in ("qpos", "qvel", "act", "plugin_state"):
            if not np.all(np.isfinite(getattr(d, name))):
                problems.append(f"non-finite {name} at step {i}")
        if problems:
            break
    for name, w in mujoco.mjtWarning.__members__.items():
        if w != mujoco.mjtWarning.mjNWARNING and d.warning[int(w)].number:
            problems.append(f"{name} x{d.warning[int(w)].number} (info {d.warning[int(w)].lastinfo})")
    return problems


def _included_names() -> set[str]:
    return {name for path in ASSETS_DIR.glob("*.xml")
            for name in re.findall(r'<include\s+file="([^"]+)"', path.read_text())}


@pytest.mark.parametrize("path", sorted(ASSETS_DIR.glob("*.xml")), ids=lambda p: p.name)
def test_shipped_scene_survives_random_torque(path):
    try:
        model = load_model(path)
    except ValueError as exc:
        if path.name in _included_names():
            pytest.skip(f"{path.name} is included by another asset and does not compile alone: {exc}")
        raise
    assert rollout_problems(model, random_controls(model, seed=0)) == []


VARIANTS = {
    "rigid_rod": (ArmSpec(segments=0), JointParams()),
    "one_segment": (ArmSpec(segments=1), JointParams()),
    "four_segments": (ArmSpec(segments=4), JointParams()),
    "eight_segments": (ArmSpec(segments=8), JointParams()),
    "input_delay_2ms": (ArmSpec(input_delay=2e-3), JointParams()),
    "no_gravity": (ArmSpec(gravity=False), JointParams()),
    "friction_2sep": (ArmSpec(), JointParams(friction=TwoSEP())),
    "friction_static": (ArmSpec(), JointParams(friction=StaticFriction())),
    "friction_none": (ArmSpec(), JointParams(friction=None)),
    "backlash": (ArmSpec(), JointParams(transmission=Transmission(backlash=2e-3))),
}


@pytest.mark.parametrize("name", list(VARIANTS))
def test_arm_variant_survives_random_torque(name):
    arm, joint = VARIANTS[name]
    model = load_model(build_arm(arm, joint))
    assert rollout_problems(model, random_controls(model, seed=1)) == []


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_default_arm_survives_a_full_range_torque_step(sign):
    """A step to the actuator's limit (20 A: 5 N m at the motor, 800 N m at the link), 0.5 s.

    Guards the explicit stiffness against the hub's mode: behind the gear the transmission
    spring sees the hub (plus the first segment's armature, ~3e-3 kg m^2), not the whole link;
    with k3 = 1e9 its tangent stiffness at the deflection of a 2 N m step put w h past 2 at
    0.5 ms and MuJoCo reset the diverged state.
    """
    model = load_model(build_arm())
    ctrl = np.full((int(0.5 / model.opt.timestep), model.nu), sign * model.actuator_ctrlrange[0, 1])
    assert rollout_problems(model, ctrl) == []
