"""The two shipped arms (``arm2_planar.xml``, ``arm3.xml``): their joints, and their XML written
with a comment on every element (``python -m mjjoint.assets.shipped_arms`` regenerates them).
"""
from __future__ import annotations

import textwrap

from ..joint import JointParams
from ..physics.transmission import Transmission
from ..physics.twosep import TwoSEP
from .builder import ASSETS_DIR
from .serial import ROTOR_LENGTH, ROTOR_OFFSET, JointSpec, build_serial_arm


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
  Units: SI. Generated by mjjoint.assets.shipped_arms (python -m mjjoint.assets.shipped_arms); edit the
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
  Units: SI. Generated by mjjoint.assets.shipped_arms (python -m mjjoint.assets.shipped_arms); edit the
  JointSpecs there, not this file."""),
}


def shipped_xml(filename: str) -> str:
    """The text of a shipped arm asset, as ``python -m mjjoint.assets.shipped_arms`` writes it."""
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
