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

Also here: per-joint model files (``[[joint]]`` entries), scripted joint-space tracking with
a motor-side PD controller, per-joint recordings, and the two shipped arms
(``python -m mjjoint.assets.multi`` regenerates mjjoint/assets/mjcf/arm2_planar.xml and arm3.xml).
"""
from __future__ import annotations

import dataclasses
import textwrap
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import yaml

from ..coupling.plugin import PLUGIN_NAME, register
from ..joint import JointParams
from ..modelfile import ModelFile, Simulation, _one_line, from_section, load_model_file, parse_model
from ..params import check
from ..physics.transmission import Transmission
from ..physics.twosep import TwoSEP
from ..recordings import MultiRecording, Recording, write_recording
from ..sim import FULL, Simulator, Trace, check_diverged
from .builder import ASSETS_DIR, ArmSpec, load_model
from .stability import check_model_stability
from .stability import stable_timesteps as model_stable_timesteps

ROTOR_OFFSET = 0.13   # [m] rotor centre behind the mount along the axis, as in elastic_joint.xml
ROTOR_LENGTH = 0.06   # [m] the rotor as a solid cylinder of this length: its transverse inertia
HOUSING_RADIUS, HOUSING_LENGTH = 0.05, 0.08  # [m] gear casing, a solid cylinder ahead of the rotor
STEEL_DENSITY = 7800.0  # [kg/m^3] sizes the drawn tip weight (1 kg -> r = 31 mm, as in the single arm)
PHYSICS = ("friction", "transmission", "hysteresis", "load_friction", "ripple")


def _unit(name: str, v: Any) -> tuple[float, float, float]:
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
        axis, direction = _unit("axis", self.axis), _unit("direction", self.direction)
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


# ---- building -----------------------------------------------------------------------------

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
                      pos=(0.0, 0.0, 0.0)) -> mujoco.MjsBody:
    """Mount joint ``i`` (housing, rotor, hub, rod, actuator, plugin, sensors) on ``parent``.

    Returns the rod's tip body, where the next joint mounts.
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
    plugin = spec.add_plugin(plugin_name=PLUGIN_NAME, name=f"joint{i}")
    plugin.config = js.joint.replace(motor_joint=f"motor{i}", link_joint=f"link{i}").to_config()
    for kind, name, joint in ((mujoco.mjtSensor.mjSENS_JOINTPOS, "q", "motor"),
                              (mujoco.mjtSensor.mjSENS_JOINTPOS, "theta", "link"),
                              (mujoco.mjtSensor.mjSENS_JOINTVEL, "qd", "motor"),
                              (mujoco.mjtSensor.mjSENS_JOINTVEL, "thetad", "link")):
        spec.add_sensor(name=f"{name}{i}", type=kind, objtype=mujoco.mjtObj.mjOBJ_JOINT, objname=f"{joint}{i}")
    spec.add_sensor(name=f"u{i}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                    objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=f"current{i}")
    return tip


def build_serial_arm(joints: list[JointSpec], world: World = World(), *,
                     name: str = "mjjoint serial arm") -> mujoco.MjSpec:
    """An ``MjSpec`` of the serial arm: joint 1 on the world, joint i+1 on tip i.

    Each joint's parameters are checked against the timestep (``check_arm_stability``).
    """
    if not joints or not all(isinstance(j, JointSpec) for j in joints):
        raise ValueError("build_serial_arm needs one or more JointSpec")
    spec = new_spec(world, name)
    parent = spec.worldbody
    for i, js in enumerate(joints, start=1):
        parent = add_elastic_joint(spec, parent, i, js)
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


# ---- model files ----------------------------------------------------------------------------

@dataclass(frozen=True)
class SerialArmFile:
    """What a multi-joint model file describes (duck-types ``ModelFile``: compile, sample_rate)."""

    joints: tuple[JointSpec, ...]
    world: World = World()
    sample_rate: float = Simulation.sample_rate

    def compile(self) -> mujoco.MjModel:
        return load_model(build_serial_arm(list(self.joints), self.world))


def _read_mapping(path: Path) -> Any:
    text = path.read_text(encoding="utf-8")
    return tomllib.loads(text) if path.suffix.lower() == ".toml" else yaml.safe_load(text)


def parse_joint_entry(entry: Any, where: str) -> JointSpec:
    """One ``[[joint]]`` entry: ``arm`` (JointSpec body fields) plus the single-joint physics sections."""
    if not isinstance(entry, dict):
        raise ValueError(f"{where} must be a table of sections, not {entry!r}")
    allowed = ("arm", *PHYSICS)
    unknown = sorted(set(entry) - set(allowed), key=str)
    if unknown:
        raise ValueError(f"{where}: unknown section {unknown[0]!r} (allowed: {', '.join(allowed)})")
    try:
        params = parse_model({k: v for k, v in entry.items() if k in PHYSICS}).joint
    except ValueError as exc:
        raise ValueError(f"{where}.{exc}") from None
    body = dict(entry.get("arm", {}))
    vectors = {k: _unit(f"{where}.arm.{k}", body.pop(k)) for k in ("axis", "direction") if k in body}
    return from_section(JointSpec, body, f"{where}.arm", joint=params, **vectors)


def parse_serial_arm(data: Any) -> SerialArmFile:
    """A ``SerialArmFile`` from the parsed mapping: [simulation], [world], [[joint]] entries."""
    if not isinstance(data, dict) or not isinstance(data.get("joint"), list) or not data["joint"]:
        raise ValueError("a multi-joint model file needs one or more [[joint]] entries")
    unknown = sorted(set(data) - {"simulation", "world", "joint"}, key=str)
    if unknown:
        raise ValueError(f"unknown section {unknown[0]!r} (allowed: simulation, world, joint)")
    joints = tuple(parse_joint_entry(e, f"joint[{k}]") for k, e in enumerate(data["joint"], start=1))
    return SerialArmFile(
        joints=joints, world=from_section(World, data.get("world", {}), "world"),
        sample_rate=from_section(Simulation, data.get("simulation", {}), "simulation").sample_rate)


def load_serial_arm_file(path: str | Path) -> SerialArmFile:
    """Read a .toml or .yaml/.yml multi-joint model; every problem is a one-line ``ValueError``."""
    path = Path(path)
    if path.suffix.lower() not in (".toml", ".yaml", ".yml"):
        raise ValueError(f"{path}: multi-joint model files are .toml, .yaml or .yml")
    try:
        return parse_serial_arm(_read_mapping(path))
    except (ValueError, yaml.YAMLError, OSError) as exc:
        raise ValueError(f"{path}: {_one_line(exc)}") from None


def read_model_file(path: str | Path) -> ModelFile | SerialArmFile:
    """A single-joint model file, an MJCF, or (a ``[[joint]]`` list) a multi-joint model file."""
    path = Path(path)
    if path.suffix.lower() in (".toml", ".yaml", ".yml") and path.is_file():
        try:
            data = _read_mapping(path)
        except (ValueError, yaml.YAMLError, OSError):
            data = None  # load_model_file reports it
        if isinstance(data, dict) and isinstance(data.get("joint"), list):
            return load_serial_arm_file(path)
    return load_model_file(path)


# ---- simulation helpers ---------------------------------------------------------------------

def track(sim: Simulator, q_ref_link: np.ndarray, kp, kd,
          initial_state: np.ndarray | None = None) -> list[Trace]:
    """Follow link angles ``q_ref_link`` (n, njoint) with a PD controller on each motor.

    u_j = kp_j (N_j theta_ref_j - q_j) + kd_j (N_j theta_ref_j' - q_j'), from the motor-side
    q and q' at each sample (the chapter's setups measure the motor encoder), clipped to the
    actuator range and held for the sample. Per-sample Python: a scripting tool, not a
    rollout. Returns one Trace per joint, u being the torque applied.
    """
    ref = np.asarray(q_ref_link, dtype=float)
    nj = len(sim.joints)
    if ref.ndim != 2 or ref.shape[1] != nj or len(ref) < 1:
        raise ValueError(f"q_ref_link must have shape (n, {nj}), got {ref.shape}")
    if not np.all(np.isfinite(ref)):
        raise ValueError("q_ref_link contains NaN or inf")
    kp = np.broadcast_to(np.asarray(kp, float), (nj,))
    kd = np.broadcast_to(np.asarray(kd, float), (nj,))
    for name, g in (("kp", kp), ("kd", kd)):
        for v in g:
            check(name, v, 0.0)
    m, d = sim.model, sim.data
    gear = np.array([j.gear_ratio for j in sim.joints])
    km = np.array([j.k_m for j in sim.joints])
    mq = [j.motor_qpos for j in sim.joints]
    md = [j.motor_dof for j in sim.joints]
    act = [j.actuator for j in sim.joints]
    if min(act) < 0:
        raise ValueError("every joint needs an actuator on its motor joint")
    limited = m.actuator_ctrllimited[act].astype(bool)
    lo = np.where(limited, m.actuator_ctrlrange[act, 0] * km, -np.inf)
    hi = np.where(limited, m.actuator_ctrlrange[act, 1] * km, np.inf)
    ref_rate = np.gradient(ref, 1.0 / sim.sample_rate, axis=0) if len(ref) > 1 else np.zeros_like(ref)

    x0 = sim.initial_state() if initial_state is None else np.asarray(initial_state, float)
    mujoco.mj_setState(m, d, x0, FULL)
    d.ctrl[:] = 0.0
    states = np.empty((len(ref) + 1, len(x0)))
    states[0] = x0
    u = np.empty_like(ref)
    for k in range(len(ref)):
        u[k] = np.clip(kp * (gear * ref[k] - d.qpos[mq]) + kd * (gear * ref_rate[k] - d.qvel[md]), lo, hi)
        d.ctrl[act] = u[k] / km
        for _ in range(sim.substeps):
            mujoco.mj_step(m, d)
        mujoco.mj_getState(m, d, states[k + 1], FULL)
    check_diverged(states[1:], x0[0])
    return sim.traces(states[:-1], u)


def recording(traces: list[Trace] | Trace) -> MultiRecording:
    """Traces as a recording: columns t, u1, q1, theta1, tau1, u2, ..."""
    traces = [traces] if isinstance(traces, Trace) else list(traces)
    return MultiRecording(tuple(Recording(t=tr.t, u=tr.u, q=tr.q, theta=tr.theta, tau=tr.tau,
                                          gear_ratio=tr.gear_ratio) for tr in traces))


def write_traces_csv(path: str | Path, traces: list[Trace]) -> Path:
    """Per-joint CSV (``t,u1,q1,theta1,tau1,u2,...``) of the traces of one run."""
    write_recording(path, recording(traces))
    return Path(path)


# ---- the shipped arms -----------------------------------------------------------------------

def _small_drive() -> JointParams:
    """Elbow drive: a size-14 class harmonic drive, 100:1, with a motor half the size.

    k1 = 5e3 N m/rad, half the shoulder's, and k3 = 5e7 N m/rad^3 keeping the shoulder's
    k3/k1 (the same relative hardening of the stiffness polynomial); Coulomb and
    stiction levels halved with the motor.
    """
    return JointParams(friction=TwoSEP(fc=0.04, fs=0.06),
                       transmission=Transmission(gear_ratio=100.0, k1=5e3, k3=5e7))


# Current limit of the shipped arms: 4 A gives 160 N m at the shoulder (0.25 N m/A x 160), the
# momentary-peak order of a size-20 harmonic drive, and 50 N m at the elbow (0.125 N m/A x 100),
# a size-14's. It also bounds the deflection where the hardening spring stays explicitly stable
# at 0.5 ms: a 5 A step on the loaded shoulder (~200 N m, > 11 mrad) diverges.
MAX_CURRENT = 4.0


def planar_arm2() -> list[JointSpec]:
    """2-DOF arm in the vertical x-z plane: both axes along y, links hanging down at home."""
    return [
        # Shoulder: the shipped joint (160:1, k1 = 1e4); its rod carries the elbow as load.
        JointSpec(rod_length=0.4, segments=4, max_current=MAX_CURRENT),
        # Elbow: smaller motor and gear; the 0.3 m rod of the same tube; 1 kg weight at the end.
        JointSpec(rod_length=0.3, segments=3, rod_mass=0.255, tip_mass=1.0, motor_inertia=2.5e-5,
                  motor_mass=0.25, housing_mass=0.8, hub_mass=0.5, k_m=0.125, max_current=MAX_CURRENT,
                  joint=_small_drive()),
    ]


def arm3() -> list[JointSpec]:
    """3-DOF arm: shoulder yaw about z, then shoulder pitch and elbow about y."""
    return [
        # Yaw: a rigid horizontal bracket, 0.15 m along x (aluminium, 0.5 kg), carries the pitch joint.
        JointSpec(axis=(0, 0, 1), direction=(1, 0, 0), segments=0, rod_length=0.15, rod_mass=0.5,
                  max_current=MAX_CURRENT),
        JointSpec(rod_length=0.4, segments=4, max_current=MAX_CURRENT),
        JointSpec(rod_length=0.3, segments=3, rod_mass=0.255, tip_mass=0.5, motor_inertia=2.5e-5,
                  motor_mass=0.25, housing_mass=0.8, hub_mass=0.5, k_m=0.125, max_current=MAX_CURRENT,
                  joint=_small_drive()),
    ]


# ---- writing the shipped assets -------------------------------------------------------------

def _notes(joints: list[JointSpec], roles: tuple[str, ...], timestep_note: str) -> dict[str, str]:
    """Comments for the generated XML, keyed by the start of the line they precede."""
    notes = {
        "<option": timestep_note,
        '<default class="mjjoint">': "No contacts (the links may pass through each other); visual geoms only.",
        '<default class="housing">': "Housing, rotor and hub geoms are drawings: their bodies carry explicit inertials.",
        "<general": "Current-controlled motors (Sec. 2.1): u = k_m i, ctrl is the current in A "
                    "(MuJoCo writes <motor> as this <general>). The range is each gear's momentary-peak "
                    "torque order, which also keeps the hardening springs explicitly stable at 0.5 ms.",
        "<sensor>": "Per joint i: motor angle q{i}, link angle theta{i}, their velocities, motor torque u{i}.",
        '<key name="home"': "Hanging at rest: every hinge at 0, transmissions relaxed (gravity passes "
                            "through the axes).",
    }
    for i, (js, role) in enumerate(zip(joints, roles), start=1):
        p, tr, n = js.joint, js.joint.transmission, max(js.segments, 1)
        parent = "the world" if i == 1 else f"tip{i - 1}"
        friction = "none" if p.friction is None else (
            f"{type(p.friction).__name__} fc = {p.friction.fc:g}, fs = {p.friction.fs:g} N m")
        hyst = "none" if tr.hysteresis is None else f"Bouc-Wen mu = {tr.hysteresis.mu:g}"
        load = "none" if p.load_friction is None else f"fc = {p.load_friction.fc:g} N m"
        if js.segments > 0:
            notes[f'<default class="segment{i}">'] = (
                f"Link {i} rod: {js.segments} segments of {js.rod_length / n:g} m; a segment bends like a "
                f"hinge of stiffness EI n / L = {js.rod_ei:g} x {js.segments} / {js.rod_length:g} = "
                f"{js.rod_ei * n / js.rod_length:g} N m/rad; damping {js.segment_damping:g} N m s/rad; "
                f"armature {js.segment_armature:g} kg m^2 keeps the unresolved high modes below 2/h.")
        else:
            notes[f'<default class="segment{i}">'] = f"Link {i}: a rigid rod (no segment hinges)."
        notes[f'<instance name="joint{i}">'] = (
            f"Joint {i} ({role}): gear {tr.gear_ratio:g}:1, k1 = {tr.k1:g} N m/rad, k3 = {tr.k3:g} N m/rad^3, "
            f"D = {tr.damping:g} N m s/rad, hysteresis {hyst}; motor friction {friction}; load friction "
            f"{load}. Keys and defaults: mjjoint/joint.py.")
        notes[f'<body name="housing{i}"'] = (
            f"Joint {i} ({role}) on {parent}, axis {' '.join(f'{a:g}' for a in js.axis)}. Gear casing and "
            f"stator: {js.housing_mass:g} kg, part of {parent}.")
        notes[f'<body name="rotor{i}"'] = (
            f"Rotor {i} on {parent}, {ROTOR_OFFSET:g} m behind the gear: {js.motor_mass:g} kg, "
            f"{js.motor_inertia:g} kg m^2 about the axis (transverse: a solid cylinder {ROTOR_LENGTH:g} m long)."
            + ("" if i == 1 else f" Its reaction and inertia load {parent} through the multibody dynamics."))
        notes[f'<body name="hub{i}"'] = f"Output hub {i} (theta{i}): {js.hub_mass:g} kg, {js.hub_inertia:g} kg m^2."
        notes[f'<body name="segment{i}_1"'] = (
            f"Rod {i}: {js.rod_length:g} m, {js.rod_mass:g} kg ({js.rod_mass / n:g} kg per segment), "
            f"along {' '.join(f'{a:g}' for a in js.direction)} at home.")
        if js.tip_mass > 0:
            notes[f'<body name="tip{i}"'] = f"Weight at the rod end: {js.tip_mass:g} kg of steel."
    return notes


def annotate(xml: str, notes: dict[str, str]) -> str:
    """Insert each note as an XML comment before the first line starting with its key."""
    lines = xml.splitlines()
    out = []
    for line in lines:
        stripped = line.lstrip()
        key = next((k for k in notes if stripped.startswith(k)), None)
        if key is not None:
            indent = line[:len(line) - len(stripped)]
            out += textwrap.wrap(f"<!-- {notes.pop(key)} -->", width=100, initial_indent=indent,
                                 subsequent_indent=indent + "     ", break_on_hyphens=False)
        out.append(line)
    if notes:
        raise ValueError(f"no line for the note {next(iter(notes))!r}")
    return "\n".join(out) + "\n"


TIMESTEP_NOTE = ("0.5 ms as in the single arm: the fastest linearised mode at home (the rods' "
                 "discretisation modes and each transmission against its hub) is 2790 rad/s, "
                 "w h = 1.4 < 2 under semi-implicit Euler; the builder checked each joint's "
                 "stable_timestep with the inertias it meets in the chain.")

SHIPPED = {
    "arm2_planar.xml": dict(
        name="mjjoint planar arm 2", joints=planar_arm2, roles=("shoulder", "elbow"),
        header="""\
  Two-link planar arm of two elastic joints (Ruderman 2012, Eq. 1 with the joint of Figs. 1, 7
  at each axis): shoulder and elbow both turn about +y, so the arm swings in the vertical x-z
  plane; theta = 0 hangs down. The shoulder is the shipped joint (elastic_joint.xml: 160:1,
  k1 = 1e4 N m/rad, 2SEP motor friction, Bouc-Wen hysteresis, bearing friction) whose 0.4 m
  rod carries the elbow; the elbow is a smaller drive (100:1, k1 = 5e3 N m/rad) with a 0.3 m
  rod and a 1 kg weight.
  Every joint i: rotor on hinge motor{i} (q) mounted on the previous link, hub on hinge
  link{i} (theta), flexible rod (hinges flex{i}_k), actuator current{i}, and its own
  mjjoint.joint instance joint{i}; the coupling between the joints is MuJoCo's multibody
  dynamics (M, C, G of Eq. 1), the plugin adds only each joint's own torques.
  Units: SI. Generated by mjjoint.assets.multi (python -m mjjoint.assets.multi); edit the
  JointSpecs there, not this file."""),
    "arm3.xml": dict(
        name="mjjoint arm 3", joints=arm3, roles=("shoulder yaw", "shoulder pitch", "elbow"),
        header="""\
  Three-joint arm of elastic joints (Ruderman 2012, Eq. 1 with the joint of Figs. 1, 7 at each
  axis): shoulder yaw about +z carries a rigid 0.15 m bracket along +x; at its end the shoulder
  pitch (+y, the shipped joint, 0.4 m flexible rod) and the elbow (+y, 100:1, 0.3 m rod,
  0.5 kg weight). At home the upper arm and forearm hang down; theta = 0 everywhere.
  Every joint i: rotor on hinge motor{i} (q) mounted on the previous link, hub on hinge
  link{i} (theta), rod (hinges flex{i}_k where flexible), actuator current{i}, and its own
  mjjoint.joint instance joint{i}; the coupling between the joints (including the gyroscopic
  reaction of the pitch rotors when the arm yaws) is MuJoCo's multibody dynamics.
  Units: SI. Generated by mjjoint.assets.multi (python -m mjjoint.assets.multi); edit the
  JointSpecs there, not this file."""),
}


def shipped_xml(filename: str) -> str:
    """The text of a shipped arm asset, as ``python -m mjjoint.assets.multi`` writes it."""
    entry = SHIPPED[filename]
    joints = entry["joints"]()
    spec = build_serial_arm(joints, name=entry["name"])
    body = annotate(spec.to_xml(), _notes(joints, entry["roles"], TIMESTEP_NOTE))
    return f"<!--\n{entry['header']}\n-->\n{body}"


def main() -> None:
    for filename in SHIPPED:
        path = ASSETS_DIR / filename
        path.write_text(shipped_xml(filename), encoding="utf-8")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
