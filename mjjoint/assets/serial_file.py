"""Multi-joint model files: ``[simulation]``, ``[world]`` and one ``[[joint]]`` entry per joint.

Each ``[[joint]]`` holds ``arm`` (the ``JointSpec`` body fields) and the single-joint physics
sections of ``modelfile``; ``read_model_file`` tells a multi-joint file from a single-joint one.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import yaml

from ..modelfile import ModelFile, Simulation, as_section, from_section, load_model_file, one_line, parse_model
from .builder import load_model
from .serial import JointSpec, World, build_serial_arm, unit_vector

PHYSICS = ("friction", "transmission", "hysteresis", "load_friction", "ripple")


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
    body = dict(as_section(entry.get("arm", {}), f"{where}.arm"))
    vectors = {k: unit_vector(f"{where}.arm.{k}", body.pop(k)) for k in ("axis", "direction") if k in body}
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
        raise ValueError(f"{path}: {one_line(exc)}") from None


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
