"""The arm whose multibody dynamics carries the other joints' measured motion to joint j."""
from __future__ import annotations

from pathlib import Path

import mujoco

from ..assets import load_model
from ..assets.serial_file import SerialArmFile, read_model_file
from ..coupling.plugin import register_model
from ..modelfile import ModelFile, one_line, shipped
from ..sim import joint_indices


def arm_model(arm: SerialArmFile | str | Path, n_joints: int, name: str = "arm") -> mujoco.MjModel:
    """The compiled arm: a ``[[joint]]`` model file (or its ``SerialArmFile``) or an MJCF whose
    ``mjjoint.joint`` instances are the recording's joints 1..n in order (one-line ValueError)."""
    if isinstance(arm, (str, Path)):
        path = shipped(Path(arm))
        if not path.is_file():
            raise ValueError(f"{name} {path}: no such file")
        if path.suffix.lower() == ".xml":
            try:
                model = load_model(path)
            except ValueError as exc:
                raise ValueError(f"{name} {path}: {exc}") from None
            except Exception as exc:  # MuJoCo's compiler: its message, on one line
                raise ValueError(f"{name} {path}: {one_line(exc)}") from None
        else:
            arm = read_model_file(path)
            if isinstance(arm, ModelFile):
                raise ValueError(f"{name} {path}: a single-joint model file; the arm needs a [[joint]] "
                                 "model file or an MJCF of the whole arm")
            model = arm.compile()
    else:
        model = arm.compile()
    register_model(model)
    found = len(joint_indices(model)) if model.nplugin else 0
    if found != n_joints:
        raise ValueError(f"{name} has {found} mjjoint joints; the recording holds {n_joints} "
                         "(each joint of the arm needs its columns u, q, theta in the recording, in order)")
    return model
