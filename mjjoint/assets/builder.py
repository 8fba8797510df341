"""Variants of the shipped single-joint arm, built with MuJoCo's own ``MjSpec``.

The commented ``mjjoint/assets/mjcf/elastic_joint.xml`` is the source of truth; ``build_arm`` loads
it and changes only what an ``ArmSpec`` or ``JointParams`` says, so every variant keeps the
asset's classes, sensors and keyframe. MjSpec (not dm_control.mjcf) because it round-trips
``<extension><plugin>`` configs and compiles in-process without an XML detour.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ..coupling.plugin import PLUGIN_NAME, register, register_model
from ..joint import GROUND, JointParams, split_config
from ..params import check
from .stability import check_model_stability

ASSETS_DIR = Path(os.environ.get("MJJOINT_ASSETS", Path(__file__).resolve().parent / "mjcf"))
ARM_XML = "elastic_joint.xml"
# History reserved whenever a delay is on, so models differing only in the delay value keep one
# size signature (mujoco.rollout batches need that): MAX_DELAY_SAMPLES steps, or as many as
# MAX_DELAY_S takes where that is more, so that a model at a fine step (a flexible rod's) still
# holds every delay the identification fits (``input_delay.delay``, 0 to 10 ms).
MAX_DELAY_SAMPLES = 24
MAX_DELAY_S = 0.01


def delay_samples(timestep: float) -> int:
    """The control history's length [steps] of a model at ``timestep`` with a delay."""
    return max(MAX_DELAY_SAMPLES, math.ceil(MAX_DELAY_S / timestep))


def max_delay(timestep: float) -> float:
    """The longest input delay [s] a model at ``timestep`` holds."""
    return delay_samples(timestep) * timestep


# The longest first-order input lag [s] a plant may have: a current loop of 1.6 Hz bandwidth.
MAX_LAG_S = 0.1


def scene_path(name: str = "scene.xml") -> Path:
    path = ASSETS_DIR / name
    if not path.exists():
        raise FileNotFoundError(f"MJCF asset {path} not found (set MJJOINT_ASSETS to the mjjoint/assets/mjcf folder)")
    return path


@dataclass(frozen=True)
class ArmSpec:
    """Body-level parameters of the arm; defaults equal the shipped XML (see its comments)."""

    segments: int = 4               # flexible rod segments (Fig. 5 (b)); 0 = rigid rod
    rod_length: float = 0.4         # [m]
    rod_mass: float = 0.34          # [kg], aluminium d = 20 mm
    rod_ei: float = 550.0           # bending stiffness EI [N m^2]
    segment_damping: float = 0.5    # [N m s/rad] per segment hinge
    segment_armature: float = 1e-3  # [kg m^2] regularises the rod's unresolved high modes
    tip_mass: float = 1.0           # [kg] adjustable weight at the rod end
    motor_inertia: float = 5e-5     # [kg m^2] rotor + coupling + wave generator
    hub_inertia: float = 2e-3       # [kg m^2]
    k_m: float = 0.25               # motor torque constant [N m/A]
    max_current: float = 20.0       # [A] amplifier limit, the actuator's ctrlrange (5 N m at k_m)
    gravity: float = 9.81           # [m/s^2]; 0 (or False) switches gravity off
    input_delay: float = 0.0        # [s] current-to-torque delay (native actuator delay)
    input_lag: float = 0.0          # [s] time constant of the current loop's first-order lag; 0 none
    input_offset: float = 0.0       # [N m] constant motor torque added to u (amplifier offset)
    timestep: float = 5e-4          # [s]

    def __post_init__(self) -> None:
        if int(self.segments) != self.segments or not 0 <= self.segments <= 20:
            raise ValueError(f"segments={self.segments!r} is outside the allowed range [0, 20] (integer)")
        check("rod_length", self.rod_length, 0.0, 5.0, lo_open=True)
        check("rod_mass", self.rod_mass, 0.0, 100.0, lo_open=True)
        check("rod_ei", self.rod_ei, 0.0, lo_open=True)
        check("segment_damping", self.segment_damping, 0.0)
        check("segment_armature", self.segment_armature, 0.0)
        check("tip_mass", self.tip_mass, 0.0, 1e6)  # an industrial link as a tip on the 0.4 m rod: 1e3s of kg
        check("motor_inertia", self.motor_inertia, 0.0, lo_open=True)
        check("hub_inertia", self.hub_inertia, 0.0, lo_open=True)
        check("k_m", self.k_m, 0.0, lo_open=True)
        check("max_current", self.max_current, 0.0, lo_open=True)
        check("timestep", self.timestep, 1e-6, 0.01)
        check("gravity", self.gravity, 0.0, 100.0)
        check("input_delay", self.input_delay, 0.0, max_delay(self.timestep))
        check("input_lag", self.input_lag, 0.0, MAX_LAG_S)
        check("input_offset", self.input_offset, -1e3, 1e3)

    @property
    def link_inertia(self) -> float:
        """Rigid-link inertia about the hub [kg m^2] (for stability estimates)."""
        return self.hub_inertia + self.rod_mass * self.rod_length ** 2 / 3 + self.tip_mass * self.rod_length ** 2

    @property
    def scales(self) -> dict[str, float]:
        """Orders of motor-side torque, speed and angle: the units the effect ranges are set in."""
        return {"force": 1.0, "speed": 1.0, "position": 1.0}

    def unit(self, rotary: str) -> str:
        """The unit of a quantity given in the motor's rotary units (the same here)."""
        return rotary

    @property
    def hinge_stiffness(self) -> float:
        """Each segment hinge's stiffness [N m/rad]: EI over the segment's length."""
        return self.rod_ei * max(self.segments, 1) / self.rod_length

    @property
    def link_parameter(self) -> str:
        """How identification fits the link's inertia: as the tip mass (the payload is what is
        uncertain; it moves the inertia both ways) or, on a link without one, the hub inertia."""
        return "mass.tip" if self.tip_mass > 0 else "inertia.link"


def lag_constant(lag: float, timestep: float) -> float:
    """The ``filterexact`` time constant whose step is backward Euler's for a first-order ``lag``:
    exp(-h / T) = lag / (lag + h)."""
    return timestep / math.log1p(timestep / lag)


def set_input(act, k_m: float, offset: float, delay: float, timestep: float, lag: float = 0.0) -> None:
    """Motor input u = k_m ctrl + offset, applied ``delay`` late and, with ``lag`` > 0, through a
    first-order lag of that time constant (native actuator terms) in a model stepped at
    ``timestep``.

    The offset is an affine actuator bias in ctrl units (MuJoCo multiplies the actuator force,
    gain ctrl + bias, by the gear k_m). The lag is the actuator's activation and lags the
    current, not the offset. The step's force is the activation at its end (``actearly``), so a
    vanishing lag is the unlagged input, not one a step late; and the activation steps as
    backward Euler does, a <- (lag a + h c) / (lag + h) (``filterexact`` with the time constant
    ``lag_constant``), so that against the step's centred control it lags a slow command by
    ``lag`` exactly where the exact step of ``lag`` itself would lag it by lag - h/2.
    """
    act.gear[0] = k_m
    if lag > 0:
        act.dyntype = mujoco.mjtDyn.mjDYN_FILTEREXACT
        act.dynprm[0] = lag_constant(lag, timestep)
        act.actearly = 1
    else:
        act.dyntype = mujoco.mjtDyn.mjDYN_NONE
        act.actearly = 0
    if offset != 0.0:
        act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        act.biasprm[0] = offset / k_m
    else:
        act.biastype = mujoco.mjtBias.mjBIAS_NONE
    if delay > 0:
        act.delay = delay
        act.nsample = delay_samples(timestep) + 2
        # Linear interpolation of the control history: with MuJoCo's default zero-order hold a
        # delay between two steps is rounded up to the next (1.6 ms delivered 2.0 ms at h = 0.5 ms);
        # interpolated, a held input arrives exactly ``delay`` late in impulse, as the windows'
        # delayed hold (identify/windows.py) models it.
        act.interp = 1


def _rebuild_rod(spec: mujoco.MjSpec, arm: ArmSpec) -> None:
    hub = spec.body("hub")
    old = spec.body("segment1")
    if old is not None:
        spec.delete(old)
    seg_default = spec.find_default("segment")
    n = max(arm.segments, 1)
    length = arm.rod_length / n
    parent = hub
    for i in range(1, n + 1):
        body = parent.add_body(name=f"segment{i}", pos=[0, 0, 0 if i == 1 else -length])
        body.classname = seg_default
        if arm.segments > 0:
            joint = body.add_joint(name=f"flex{i}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 1, 0])
            joint.classname = seg_default
            joint.stiffness[0] = arm.hinge_stiffness
            joint.damping[0] = arm.segment_damping
            joint.armature = arm.segment_armature
        geom = body.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[0.01, 0, 0],
                             fromto=[0, 0, 0, 0, 0, -length], mass=arm.rod_mass / n)
        geom.classname = seg_default
        parent = body
    tip = parent.add_body(name="tip", pos=[0, 0, -length])
    tip.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.031, 0, 0], mass=arm.tip_mass,
                 rgba=[0.8, 0.3, 0.2, 1], contype=0, conaffinity=0, group=1)
    tip.add_site(name="tip", size=[0.005, 0, 0])


def build_arm(arm: ArmSpec = ArmSpec(), joint: JointParams = JointParams(), *,
              scene: bool = True) -> mujoco.MjSpec:
    """An ``MjSpec`` of the arm with these body and joint parameters (not yet compiled)."""
    register()
    spec = mujoco.MjSpec.from_file(str(scene_path("scene.xml" if scene else ARM_XML)))
    plugin = next(p for p in spec.plugins if p.plugin_name == PLUGIN_NAME)
    plugin.config = joint.to_config()
    spec.option.timestep = arm.timestep
    spec.option.gravity = [0.0, 0.0, -float(arm.gravity)]
    rotor = spec.body("rotor")
    # Transverse entries only matter for drawing; keep them >= the axial one (triangle rule).
    transverse = max(4e-4, arm.motor_inertia)
    rotor.inertia = [transverse, arm.motor_inertia, transverse]
    spec.body("hub").inertia = [arm.hub_inertia] * 3
    _rebuild_rod(spec, arm)
    set_input(spec.actuator("current"), arm.k_m, arm.input_offset, arm.input_delay, arm.timestep, arm.input_lag)
    spec.actuator("current").ctrlrange = [-arm.max_current, arm.max_current]
    # The home keyframe must match the (possibly new) number of joints.
    for key in spec.keys:
        key.qpos = np.zeros(2 + arm.segments)
    return spec


def load_model(source: str | Path | mujoco.MjSpec | None = None, **kwargs) -> mujoco.MjModel:
    """Compile a model from an MJCF path, an ``MjSpec``, or (``None``) the default arm.

    Every ``mjjoint.joint`` instance's config is validated here, so a bad value fails with
    a one-line ``ValueError`` naming it instead of a MuJoCo plugin-init failure, and so is its
    stability at the model's timestep (``stability.check_model_stability``).
    """
    register()
    if source is None:
        spec = build_arm(**kwargs)
    elif isinstance(source, mujoco.MjSpec):
        spec = source
    else:
        path = Path(source)
        if not path.exists():
            raise FileNotFoundError(f"model file {path} does not exist")
        spec = mujoco.MjSpec.from_file(str(path))
    for plugin in spec.plugins:
        if plugin.plugin_name == PLUGIN_NAME:
            try:
                empty = [k for k, v in plugin.config.items() if v == ""]
                if empty:  # the compiled model keeps no difference between an empty value and none
                    raise ValueError(f"config key {empty[0]!r} has an empty value, which MuJoCo reads as absent: "
                                     "give a value or leave the key out")
                for cfg in split_config(dict(plugin.config)):
                    params = JointParams.from_config(cfg)
                    for name in (params.motor_joint, params.link_joint):
                        if name != GROUND and spec.joint(name) is None:
                            raise ValueError(f"joint {name!r} named in the config does not exist in the model")
            except ValueError as exc:
                raise ValueError(f"plugin instance {plugin.name!r}: {exc}") from None
    model = spec.compile()
    if model.nplugin and model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4:
        # The internal states advance once a step from its end velocities, q_new = q + h w_new
        # (coupling.kernels.joint_advance): true of Euler and the implicit integrators only.
        raise ValueError("integrator='RK4' is not supported with mjjoint.joint; use Euler, implicit "
                         "or implicitfast")
    register_model(model)
    check_model_stability(model)
    return model
