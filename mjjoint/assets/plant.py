"""One entry point for every plant the identification builds: the elastic arm or a direct drive."""
from __future__ import annotations

import mujoco

from ..joint import JointParams
from .builder import ArmSpec, build_arm
from .drive import DriveSpec, build_drive


def build_plant(plant: ArmSpec | DriveSpec, joint: JointParams) -> mujoco.MjSpec:
    """The ``MjSpec`` (without a scene) of ``plant`` with the joint physics ``joint``."""
    if isinstance(plant, DriveSpec):
        return build_drive(plant, joint)
    return build_arm(plant, joint, scene=False)
