"""One entry point for every plant the identification builds: the elastic arm or a direct drive."""
from __future__ import annotations

import mujoco
import numpy as np

from ..joint import JointParams
from .builder import ArmSpec, build_arm
from .drive import DriveSpec, build_drive


def input_range(u, k_m: float, floor: float) -> float:
    """The amplifier limit [ctrl units] that passes the recorded motor torques ``u`` unclipped:
    ``floor``, or 1 % above their largest magnitude in ctrl units (u / ``k_m``)."""
    return max(floor, 1.01 * float(np.max(np.abs(u))) / k_m)


def build_plant(plant: ArmSpec | DriveSpec, joint: JointParams) -> mujoco.MjSpec:
    """The ``MjSpec`` (without a scene) of ``plant`` with the joint physics ``joint``.

    A recorded input is what was applied, so no amplifier limit may clip it: the shipped arm's
    control range (the lab motor's 5 N m) is lifted, and a drive's is sized from the recording
    (``problem.drive_structure``)."""
    if isinstance(plant, DriveSpec):
        return build_drive(plant, joint)
    spec = build_arm(plant, joint, scene=False)
    for act in spec.actuators:
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    return spec
