"""The rigid arm a controller is usually designed on: the shipped single arm with motor and link
geared rigidly (the reference that a stiff, frictionless elastic joint must reproduce)."""
from __future__ import annotations

import mujoco
import numpy as np

from ..assets import ArmSpec, build_arm
from ..joint import JointParams


def build_rigid_arm(arm: ArmSpec = ArmSpec(), gear_ratio: float = JointParams().gear_ratio) -> mujoco.MjSpec:
    """``build_arm(arm)`` without the plugin and the motor hinge: the link hinge carries the
    rotor's reflected inertia N^2 J_m as armature and the actuator drives it with k_m N per
    ampere, so the same current moves the same rod, tip and gravity load. No joint physics."""
    spec = build_arm(arm)
    for plugin in list(spec.plugins):
        spec.delete(plugin)
    for sensor in list(spec.sensors):
        if sensor.objname == "motor":
            spec.delete(sensor)
    spec.delete(spec.joint("motor"))
    spec.joint("link").armature = gear_ratio ** 2 * arm.motor_inertia
    act = spec.actuator("current")
    act.target = "link"
    act.gear[0] = arm.k_m * gear_ratio
    for key in spec.keys:
        key.qpos = np.zeros(1 + arm.segments)
    return spec
