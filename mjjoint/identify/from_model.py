"""The starting structure a single-joint model file describes: its terms as effects, its values
as initial values, and notes on what the effect catalogue cannot hold."""
from __future__ import annotations

import math

from ..joint import JointParams
from ..modelfile import ModelFile
from ..physics.twosep import TwoSEP
from .structure import Structure


def structure_from_model(model: ModelFile, gear_ratio: float | None, *, model_name: str = "model",
                         gear_name: str = "gear_ratio") -> tuple[Structure, list[str]]:
    """The structure a model file describes, and notes on what the effect catalogue cannot hold.

    Every switched-on term becomes its effect with the file's values as initial values; the
    arm is the nominal ArmSpec (inertias, masses, timestep). A ``gear_ratio`` other than the
    file's is an error. Errors are one-line ``ValueError`` s starting with the input they are
    about, as the caller names it (``model_name``, ``gear_name``).
    """
    if model.arm is None or model.joint is None:
        raise ValueError(f"{model_name}: an MJCF (.xml) model cannot be mapped onto effects; "
                         "give a .toml/.yaml model file or the effects")
    arm, joint = model.arm, model.joint
    if (joint.motor_joint, joint.link_joint) != (JointParams.motor_joint, JointParams.link_joint):
        raise ValueError(f"{model_name}: the joint fixes a side to the world; fit and diagnose need the free arm")
    tr = joint.transmission
    if gear_ratio is not None and gear_ratio != tr.gear_ratio:
        raise ValueError(f"{gear_name} {gear_ratio:g} differs from the model file's "
                         f"transmission.gear_ratio {tr.gear_ratio:g}")
    values: dict[str, float] = {"linear_stiffness.k1": tr.k1}
    settings: dict[str, float] = {}
    notes = []
    f = joint.friction
    if f is not None and f.fc > 0:
        values["coulomb_friction.fc"] = f.fc
        if f.fs > f.fc:
            values.update({"stribeck_friction.ratio": f.fs / f.fc, "stribeck_friction.vs": f.vs})
        if f.asym != 0:
            values["friction_asymmetry.ratio"] = f.asym / f.fc
        if isinstance(f, TwoSEP):
            values.update({"dynamic_friction.k": f.k, "dynamic_friction.b": f.b})
    elif f is not None and f.fs > 0:
        notes.append("friction: break-away without a Coulomb level is not an effect; fs ignored")
    if f is not None and f.shape != 1.0:
        notes.append(f"friction.shape={f.shape:g}: the Stribeck effect has shape 1; the shape is not kept")
    if f is not None and f.sigma > 0:
        values["viscous_friction.sigma"] = f.sigma
        if f.sigma_asym != 0:
            values["viscous_asymmetry.ratio"] = f.sigma_asym
    if tr.k2 != 0:
        notes.append(f"transmission.k2={tr.k2:g}: no effect holds a quadratic stiffness term; ignored")
    if tr.k3 > 0:
        values["nonlinear_stiffness.k3"] = tr.k3
    if tr.damping > 0:
        values["transmission_damping.d"] = tr.damping
    if tr.backlash > 0:
        values["backlash.width"] = tr.backlash
    if tr.hysteresis is not None:
        bw = tr.hysteresis
        if (bw.a, bw.n) != (1.0, 1.0) or bw.beta != bw.gamma:
            notes.append("hysteresis: the effect has A = 1, n = 1, beta = gamma; only mu and x_u are kept")
        values.update({"transmission_hysteresis.mu": tr.hysteresis.mu,
                       "transmission_hysteresis.x_u": tr.hysteresis.x_ultimate})
    if joint.load_friction is not None:
        values.update({"load_friction.fc": joint.load_friction.fc,
                       "load_friction.viscous": joint.load_friction.viscous})
    if joint.ripple is not None:
        r = joint.ripple
        values.update({"torque_ripple.a": r.amplitude * math.cos(r.phase),
                       "torque_ripple.b": r.amplitude * math.sin(r.phase)})
        settings["torque_ripple.harmonic"] = r.harmonic
    if arm.gravity > 0:
        values["gravity.g"] = arm.gravity
    if arm.segments > 0:
        values["link_flexibility.ei"] = arm.rod_ei
        if arm.segments != 4:
            notes.append(f"arm.segments={arm.segments}: the link_flexibility effect models the rod with 4 segments")
    if arm.input_delay > 0:
        values["input_delay.delay"] = arm.input_delay
    effects = sorted({name.split(".")[0] for name in values})
    return Structure.create(effects, arm, tr.gear_ratio, values, settings), notes
