"""A direct drive: one motor joint carrying its load, no gear elasticity, no output encoder.

The elastic joint with its output cut free (``JointParams(transmission=None)``): a linear axis
driven through a stiff ball screw (the shipped ``mjjoint/assets/mjcf/linear_drive.xml``, the EMPS), or
a rotary servo whose one encoder sits at the output. Friction, ripple, input delay and offset
act on the single joint exactly as on the elastic arm's motor, through the same plugin.
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..coupling.plugin import PLUGIN_NAME, register
from ..joint import GROUND, JointParams
from ..params import check
from .builder import MAX_LAG_S, max_delay, scene_path, set_input

DRIVE_XML = "linear_drive.xml"
JOINT_TYPES = {"slide": mujoco.mjtJoint.mjJNT_SLIDE, "hinge": mujoco.mjtJoint.mjJNT_HINGE}
# Rotary units of the effect catalogue -> their linear counterparts on a slide.
LINEAR_UNITS = {"N m": "N", "N m s/rad": "N s/m", "N m/rad": "N/m", "rad/s": "m/s", "rad": "m",
                "1/rad": "1/m", "kg m^2": "kg"}


@dataclass(frozen=True)
class DriveSpec:
    """Body-level parameters of a direct drive; defaults equal the shipped XML (EMPS).

    Units follow the joint: m, N, kg for a slide; rad, N m, kg m^2 for a hinge.
    ``force_scale`` and ``speed_scale`` are the orders of the drive's forces and speeds; the
    identification scales its parameter ranges with them (``identify.effects.Param.dim``).
    """

    joint_type: str = "slide"
    mass: float = 95.11              # [kg] Janot et al. 2019 (see the XML)
    k_m: float = 35.15065188         # [N/V] the EMPS files' gtau
    ctrl_limit: float = 10.0         # [V] +-10 V amplifier input
    input_offset: float = 3.16       # [N] constant drive force (Janot et al.: offset -3.16 N)
    input_delay: float = 0.0         # [s]
    input_lag: float = 0.0           # [s] first-order lag of the drive force (its current loop)
    timestep: float = 1e-3           # [s] the EMPS's 1 kHz
    force_scale: float = 100.0       # [N] EMPS: Fc ~ 20 N, peak drive force ~ 150 N
    speed_scale: float = 0.01        # [m/s] EMPS peaks near 0.2 m/s
    v_eps: float = 1e-3              # [m/s] friction sign regularisation of the XML

    def __post_init__(self) -> None:
        if self.joint_type not in JOINT_TYPES:
            raise ValueError(f"joint_type={self.joint_type!r} is not allowed (allowed: {', '.join(JOINT_TYPES)})")
        check("mass", self.mass, 0.0, lo_open=True)
        check("k_m", self.k_m, 0.0, lo_open=True)
        check("ctrl_limit", self.ctrl_limit, 0.0, lo_open=True)
        check("input_offset", self.input_offset, -1e6, 1e6)
        check("timestep", self.timestep, 1e-6, 0.01)
        check("input_delay", self.input_delay, 0.0, max_delay(self.timestep))
        check("input_lag", self.input_lag, 0.0, MAX_LAG_S)
        check("force_scale", self.force_scale, 0.0, lo_open=True)
        check("speed_scale", self.speed_scale, 0.0, lo_open=True)
        check("v_eps", self.v_eps, 0.0, lo_open=True)

    @property
    def motor_inertia(self) -> float:
        return self.mass

    def unit(self, rotary: str) -> str:
        """The unit of a quantity the effect catalogue gives in rotary units."""
        return LINEAR_UNITS.get(rotary, rotary) if self.joint_type == "slide" else rotary

    @property
    def scales(self) -> dict[str, float]:
        """Force, speed and position orders (position: what one second at speed covers)."""
        return {"force": self.force_scale, "speed": self.speed_scale, "position": self.speed_scale * 1.0}


def drive_joint(joint: JointParams) -> JointParams:
    """``joint`` as a direct drive's plugin instance: no transmission, no output side."""
    return joint.replace(motor_joint="motor", link_joint=GROUND, transmission=None, load_friction=None)


def build_drive(drive: DriveSpec = DriveSpec(), joint: JointParams | None = None) -> mujoco.MjSpec:
    """An ``MjSpec`` of the drive (not yet compiled); ``joint=None`` keeps the XML's physics."""
    register()
    spec = mujoco.MjSpec.from_file(str(scene_path(DRIVE_XML)))
    if joint is not None:
        plugin = next(p for p in spec.plugins if p.plugin_name == PLUGIN_NAME)
        plugin.config = drive_joint(joint).to_config()
    spec.option.timestep = drive.timestep
    carriage = spec.body("carriage")
    spec.joint("motor").type = JOINT_TYPES[drive.joint_type]
    if drive.joint_type == "slide":
        carriage.mass = drive.mass
    else:
        carriage.inertia = [drive.mass] * 3
    act = spec.actuator("force")
    act.ctrlrange = [-drive.ctrl_limit, drive.ctrl_limit]
    set_input(act, drive.k_m, drive.input_offset, drive.input_delay, drive.timestep, drive.input_lag)
    for key in spec.keys:
        key.qpos = np.zeros(1)
    return spec
