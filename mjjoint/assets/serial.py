"""Serial manipulators built from the single elastic joint, composed with MuJoCo's ``MjSpec``.

Joint i of an arm is the shipped joint (Fig. 1, Fig. 7) mounted on the previous link's tip:
a gear casing ``housing{i}`` fixed to that link, a rotor on hinge ``motor{i}`` and a hub on
hinge ``link{i}``, both children of that link, a rod of flexible segments (hinges
``flex{i}_{k}``) ending in ``tip{i}``, the actuator ``current{i}`` (gear k_m, ctrl in A) and
its own ``mjjoint.joint`` instance ``joint{i}``. The plugin only adds each joint's own
torques; the coupling between joints (the M, C, G of Eq. 1, including the rotor reactions on
the links carrying them and their gyroscopic terms) comes from MuJoCo's multibody dynamics.

The bodies are added to one spec directly: in mujoco 3.17.0 ``MjSpec.attach`` drops the child's
``<extension>`` plugin instances, and dm_control's ``attach`` renames the joints ("j1/motor")
but not the joint names inside the plugin configs (see docs/multijoint.md).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from ..coupling.plugin import PLUGIN_NAME, register
from ..joint import JointParams, group_config
from ..params import check
from .builder import ArmSpec
from .stability import check_model_stability
from .stability import stable_timesteps as model_stable_timesteps

ROTOR_OFFSET = 0.13   # [m] rotor centre behind the mount along the axis, as in elastic_joint.xml
ROTOR_LENGTH = 0.06   # [m] the rotor as a solid cylinder of this length: its transverse inertia
HOUSING_RADIUS, HOUSING_LENGTH = 0.05, 0.08  # [m] gear casing, a solid cylinder ahead of the rotor
STEEL_DENSITY = 7800.0  # [kg/m^3] sizes the drawn tip weight (1 kg -> r = 31 mm, as in the single arm)


def unit_vector(name: str, v: Any) -> tuple[float, float, float]:
    """``v`` (3 numbers, not all zero) scaled to length 1; a one-line ``ValueError`` otherwise."""
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={v!r} must be 3 numbers") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
        raise ValueError(f"{name}={v!r} must be 3 finite numbers, not all zero")
    return tuple(float(x) for x in a / np.linalg.norm(a))


@dataclass(frozen=True)
class JointSpec:
    """One joint of a serial arm: where it sits, its bodies, and its physics.

    Body fields mean what they mean in ``ArmSpec`` (and are checked by it); the link rod
    starts at the hub and runs along ``direction``. ``joint``'s motor_joint/link_joint are
    replaced by the builder's names (motor{i}, link{i}).
    """

    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)       # in the previous link's frame
    direction: tuple[float, float, float] = (0.0, 0.0, -1.0)  # rod at home, across the axis
    segments: int = 4
    rod_length: float = 0.4         # [m]
    rod_mass: float = 0.34          # [kg]
    rod_ei: float = 550.0           # [N m^2]
    segment_damping: float = 0.5    # [N m s/rad]
    segment_armature: float = 1e-3  # [kg m^2]
    tip_mass: float = 0.0           # [kg] weight at the rod end (the next joint is load enough)
    motor_inertia: float = 5e-5     # [kg m^2] about the axis
    motor_mass: float = 0.4         # [kg] rotor, carried by the previous link
    housing_mass: float = 1.5       # [kg] stator + gear casing, part of the previous link
    hub_inertia: float = 2e-3       # [kg m^2]
    hub_mass: float = 0.8           # [kg]
    k_m: float = 0.25               # [N m/A]
    max_current: float = 20.0       # [A] actuator ctrlrange
    joint: JointParams = JointParams()

    def __post_init__(self) -> None:
        axis, direction = unit_vector("axis", self.axis), unit_vector("direction", self.direction)
        # The segments bend about the joint axis, in the plane the link sweeps: the rod must
        # cross the axis (also what the rigid-rod inertia estimates assume).
        if abs(np.dot(axis, direction)) > 1e-9:
            raise ValueError(f"direction={self.direction!r} must be perpendicular to axis={self.axis!r}")
        object.__setattr__(self, "axis", axis)
        object.__setattr__(self, "direction", direction)
        self.arm_spec()  # ArmSpec checks the fields the two share
        check("motor_mass", self.motor_mass, 0.0, lo_open=True)
        check("housing_mass", self.housing_mass, 0.0)
        check("hub_mass", self.hub_mass, 0.0, lo_open=True)
        check("max_current", self.max_current, 0.0, lo_open=True)
        if not isinstance(self.joint, JointParams):
            raise ValueError(f"joint={self.joint!r} must be a JointParams")

    def arm_spec(self) -> ArmSpec:
        """This joint's bodies as a single-joint ``ArmSpec`` (the shared fields)."""
        names = {f.name for f in dataclasses.fields(ArmSpec)} & {f.name for f in dataclasses.fields(self)}
        return ArmSpec(**{n: getattr(self, n) for n in names})


@dataclass(frozen=True)
class World:
    """Model-wide settings of an arm (checked like the single arm's)."""

    timestep: float = 5e-4  # [s]
    gravity: float = 9.81   # [m/s^2]

    def __post_init__(self) -> None:
        ArmSpec(timestep=self.timestep, gravity=self.gravity)
def new_spec(world: World = World(), name: str = "mjjoint serial arm") -> mujoco.MjSpec:
    """An empty arm spec: options, the plugin, and the classes every joint's bodies use."""
    register()
    spec = mujoco.MjSpec()
    spec.modelname = name
    spec.option.timestep = world.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.gravity = [0.0, 0.0, -float(world.gravity)]
    spec.activate_plugin(PLUGIN_NAME)
    base = spec.add_default("mjjoint", spec.default)
    base.geom.contype = 0  # no contacts: the arm is drawn, not collided
    base.geom.conaffinity = 0
    base.geom.group = 1
    for cls, rgba in (("housing", [0.35, 0.35, 0.4, 0.6]), ("rotor", [0.25, 0.25, 0.3, 1]),
                      ("hub", [0.6, 0.6, 0.65, 1])):
        d = spec.add_default(cls, base)
        d.geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
        d.geom.rgba = rgba
        d.geom.mass = 0  # drawn only: the bodies carry explicit inertials
    return spec


def _inertial(body: mujoco.MjsBody, mass: float, axis: tuple, axial: float, transverse: float,
              pos=(0.0, 0.0, 0.0)) -> None:
    """Explicit inertial at ``pos``, symmetric about ``axis``."""
    body.mass = mass
    body.ipos = pos  # without it to_xml drops the <inertial> element
    k = np.flatnonzero(np.abs(axis) == 1.0)
    if k.size:  # a coordinate axis: a diagonal inertia, written exactly
        diag = np.full(3, transverse)
        diag[k[0]] = axial
        body.inertia = diag
    else:
        quat = np.empty(4)
        mujoco.mju_quatZ2Vec(quat, np.asarray(axis, float))
        body.iquat = quat
        body.inertia = [transverse, transverse, axial]
    body.explicitinertial = True


def _cylinder_inertia(mass: float, radius: float, length: float) -> tuple[float, float]:
    """(axial, transverse) inertia of a solid cylinder about its centre."""
    return mass * radius ** 2 / 2, mass * (3 * radius ** 2 + length ** 2) / 12


def add_elastic_joint(spec: mujoco.MjSpec, parent: mujoco.MjsBody, i: int, js: JointSpec,
                      pos=(0.0, 0.0, 0.0), *, plugin: bool = True) -> mujoco.MjsBody:
    """Mount joint ``i`` (housing, rotor, hub, rod, actuator, plugin, sensors) on ``parent``.

    Returns the rod's tip body, where the next joint mounts. ``plugin=False`` leaves out its
    plugin instance (one instance then drives every joint: ``build_serial_arm``).
    """
    axis, direction, pos = np.array(js.axis), np.array(js.direction), np.asarray(pos, float)
    n = max(js.segments, 1)
    length = js.rod_length / n
    seg = spec.add_default(f"segment{i}", spec.find_default("mjjoint"))
    if js.segments > 0:
        seg.joint.type = mujoco.mjtJoint.mjJNT_HINGE
        seg.joint.axis = axis
        seg.joint.stiffness[0] = js.rod_ei * n / js.rod_length  # EI / (L/n) per segment hinge
        seg.joint.damping[0] = js.segment_damping
        seg.joint.armature = js.segment_armature
    seg.geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
    seg.geom.size = [0.01, 0, 0]
    seg.geom.rgba = [0.75, 0.75, 0.8, 1]

    housing = parent.add_body(name=f"housing{i}", pos=pos, childclass="housing")
    _inertial(housing, js.housing_mass, js.axis,
              *_cylinder_inertia(js.housing_mass, HOUSING_RADIUS, HOUSING_LENGTH), pos=-0.06 * axis)
    housing.add_geom(size=[HOUSING_RADIUS, 0, 0], fromto=[*(-0.02 * axis), *(-0.10 * axis)])

    rotor = parent.add_body(name=f"rotor{i}", pos=pos - ROTOR_OFFSET * axis, childclass="rotor")
    r2 = 2 * js.motor_inertia / js.motor_mass  # radius^2 of the solid-cylinder rotor
    _inertial(rotor, js.motor_mass, js.axis, js.motor_inertia,
              js.motor_mass * (3 * r2 + ROTOR_LENGTH ** 2) / 12)
    rotor.add_joint(name=f"motor{i}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis)
    rotor.add_geom(size=[0.035, 0, 0], fromto=[*(-0.03 * axis), *(0.03 * axis)])
    rotor.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.006, 0, 0], pos=0.03 * (direction + axis),
                   rgba=[0.9, 0.5, 0.1, 1])  # shows the rotor turning

    hub = parent.add_body(name=f"hub{i}", pos=pos, childclass="hub")
    _inertial(hub, js.hub_mass, js.axis, js.hub_inertia, js.hub_inertia)
    hub.add_joint(name=f"link{i}", type=mujoco.mjtJoint.mjJNT_HINGE, axis=axis)
    hub.add_geom(size=[0.045, 0, 0], fromto=[*(-0.015 * axis), *(0.015 * axis)])

    body = hub
    for k in range(1, n + 1):
        body = body.add_body(name=f"segment{i}_{k}", pos=[0, 0, 0] if k == 1 else length * direction,
                             childclass=f"segment{i}")
        if js.segments > 0:
            body.add_joint(name=f"flex{i}_{k}")
        body.add_geom(fromto=[0, 0, 0, *(length * direction)], mass=js.rod_mass / n)
    tip = body.add_body(name=f"tip{i}", pos=length * direction)
    if js.tip_mass > 0:
        radius = round((3 * js.tip_mass / (4 * np.pi * STEEL_DENSITY)) ** (1 / 3), 3)
        tip.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[radius, 0, 0], mass=js.tip_mass,
                     rgba=[0.8, 0.3, 0.2, 1])
    tip.add_site(name=f"tip{i}", size=[0.005, 0, 0])

    act = spec.add_actuator(name=f"current{i}", target=f"motor{i}", trntype=mujoco.mjtTrn.mjTRN_JOINT,
                            ctrlrange=[-js.max_current, js.max_current])
    act.set_to_motor()
    act.gear[0] = js.k_m
    act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
    if plugin:
        instance = spec.add_plugin(plugin_name=PLUGIN_NAME, name=f"joint{i}")
        instance.config = mounted(js, i).to_config()
    for kind, name, joint in ((mujoco.mjtSensor.mjSENS_JOINTPOS, "q", "motor"),
                              (mujoco.mjtSensor.mjSENS_JOINTPOS, "theta", "link"),
                              (mujoco.mjtSensor.mjSENS_JOINTVEL, "qd", "motor"),
                              (mujoco.mjtSensor.mjSENS_JOINTVEL, "thetad", "link")):
        spec.add_sensor(name=f"{name}{i}", type=kind, objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=f"{joint}{i}")
    spec.add_sensor(name=f"u{i}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                    objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=f"current{i}")
    return tip


def mounted(js: JointSpec, i: int) -> JointParams:
    """Joint i's physics on its motor and link joints."""
    return js.joint.replace(motor_joint=f"motor{i}", link_joint=f"link{i}")


def build_serial_arm(joints: list[JointSpec], world: World = World(), *,
                     name: str = "mjjoint serial arm", one_instance: bool = False) -> mujoco.MjSpec:
    """An ``MjSpec`` of the serial arm: joint 1 on the world, joint i+1 on tip i.

    ``one_instance``: one plugin instance, ``joints``, drives every joint (its config lists
    them: ``joint.group_config``), instead of an instance ``joint{i}`` per joint; the physics
    is the same. Each joint's parameters are checked against the timestep (``check_arm_stability``).
    """
    if not joints or not all(isinstance(j, JointSpec) for j in joints):
        raise ValueError("build_serial_arm needs one or more JointSpec")
    spec = new_spec(world, name)
    parent = spec.worldbody
    for i, js in enumerate(joints, start=1):
        parent = add_elastic_joint(spec, parent, i, js, plugin=not one_instance)
    if one_instance:
        instance = spec.add_plugin(plugin_name=PLUGIN_NAME, name="joints")
        instance.config = group_config([mounted(js, i) for i, js in enumerate(joints, start=1)])
    add_home_key(spec)
    check_arm_stability(spec)
    return spec


def add_home_key(spec: mujoco.MjSpec) -> None:
    """Add the ``home`` keyframe: every hinge at 0 (links hanging as built, transmissions relaxed)."""
    model = spec.compile()
    spec.add_key(name="home", qpos=np.zeros(model.nq))


def stable_timesteps(spec: mujoco.MjSpec) -> dict[str, tuple[float, str]]:
    """Per plugin instance: ``stable_timestep`` with the inertias the joint meets in the chain."""
    return model_stable_timesteps(spec.compile())


def check_arm_stability(spec: mujoco.MjSpec) -> None:
    """Reject joints whose injected forces would be unstable at the spec's timestep."""
    check_model_stability(spec.compile(), hint="World(timestep=...)")
