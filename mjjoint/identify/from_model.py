"""The starting structure a single-joint model file describes: its terms as effects, its values
as initial values, and notes on what the effect catalogue cannot hold."""
from __future__ import annotations

import dataclasses
import math

from ..joint import SECTIONS, JointParams
from ..modelfile import ModelFile
from .effects import EFFECTS
from .structure import Structure

# Arm fields that effects switch on (the rest are the nominal arm's, kept as they are).
ARM_FIELDS = ("segments", "rod_ei", "segment_damping", "gravity", "input_delay", "input_lag", "input_offset")


def structure_from_model(model: ModelFile, gear_ratio: float | None, *, effects=None, model_name: str = "model",
                         gear_name: str = "gear_ratio") -> tuple[Structure, list[str]]:
    """The structure a model file describes, and notes on what the effect catalogue cannot hold.

    Every effect that reads a value off the model (``Effect.read``) is in the structure, with
    those values as initial values; the arm is the nominal ArmSpec (inertias, masses,
    timestep). ``effects`` (checked names) instead: those effects on the file's arm, with the
    values of the sections the file states; the file's other terms are left out. A term field the rebuilt
    structure does not reproduce gets a note. A ``gear_ratio`` other than the file's is an
    error. Errors are one-line ``ValueError`` s starting with the input they are about, as the
    caller names it (``model_name``, ``gear_name``).
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
    read_effects, values, settings = stated(model, effects)
    structure = Structure.create(read_effects if effects is None else effects, arm, tr.gear_ratio, values, settings)
    terms = None if effects is None else {EFFECTS[e].term for e in effects} & model.given
    return structure, _unheld((arm, joint), structure.model_params(), terms)


def stated(model: ModelFile, effects=None) -> tuple[list[str], dict[str, float], dict[str, float]]:
    """(the effects whose terms the model holds, their parameter values, their settings); of
    ``effects`` only, where given, and then only from the sections the file states."""
    read: dict[str, float] = {}
    found = []
    for e in EFFECTS.values():
        got = e.read((model.arm, model.joint)) if e.read is not None else None
        if got and (effects is None or (e.name in effects and (e.term or "arm") in model.given)):
            found.append(e.name)
            read.update(got)
    fitted = {p.name for e in found for p in EFFECTS[e].params}
    return (found, {k: v for k, v in read.items() if k in fitted},
            {k: v for k, v in read.items() if k not in fitted})


def _unheld(model, rebuilt, terms=None) -> list[str]:
    """Notes on each field of the model that the rebuilt structure does not reproduce (where
    ``terms`` are given, only theirs: the rest was left out on purpose)."""
    notes = []
    for name in ARM_FIELDS if terms is None else ():
        notes += _differs(f"arm.{name}", getattr(model[0], name), getattr(rebuilt[0], name))
    for section in SECTIONS:
        want, got = model[1].term(section), rebuilt[1].term(section)
        if want is None or (terms is not None and section not in terms):
            continue
        if got is None or type(got) is not type(want):
            notes.append(f"{section}: no effect holds this kind of term; it is left out")
            continue
        for f in dataclasses.fields(want):
            if "term" not in f.metadata:
                notes += _differs(f"{section}.{f.name}", getattr(want, f.name), getattr(got, f.name))
    return notes


def _differs(name: str, value: float, rebuilt: float) -> list[str]:
    if math.isclose(value, rebuilt, rel_tol=1e-9, abs_tol=0.0):
        return []
    return [f"{name}={value:g}: no effect holds it; the structure starts from {rebuilt:g}"]
