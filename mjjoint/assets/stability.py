"""Is a compiled model's injected physics stable at its timestep? Checked per plugin instance.

The plugin's torques are explicit in MuJoCo's integrator, so each instance's stiffnesses and
velocity slopes (``joint.stable_timestep``) must be small against the inertias they act on.
Those are the apparent inertias 1/(M^-1)_dd of the motor and link dofs with every other dof
free (Eq. 1's M: links behind and ahead recoil, a flexible rod decouples at its first hinge),
the smallest over the home pose and random link angles, since M depends on configuration.
Working on the compiled model makes the check hold for any MJCF, single joint or chain.
"""
from __future__ import annotations

import mujoco
import numpy as np

from ..coupling.plugin import instance_params
from ..joint import GROUND, stable_timestep

STABILITY_SAMPLES = 16  # random link configurations (besides home) at which M is evaluated


# What the mass matrix M(q) depends on: a fit compiles thousands of models that differ only in
# the joint physics, and their inertias are computed once.
_MASS_FIELDS = ("body_parentid", "body_pos", "body_quat", "body_ipos", "body_iquat", "body_mass", "body_inertia",
                "jnt_type", "jnt_bodyid", "jnt_pos", "jnt_axis", "dof_armature", "qpos0")
_INERTIAS: dict[bytes, np.ndarray] = {}


def apparent_inertias(model: mujoco.MjModel, links: list[str], samples: int = STABILITY_SAMPLES,
                      seed: int = 0) -> np.ndarray:
    """Per dof, the smallest inertia a force on it meets with every other dof free, 1 / (M^-1)_dd."""
    key = b"".join(np.ascontiguousarray(getattr(model, f)).tobytes() for f in _MASS_FIELDS)
    key += repr((links, samples, seed)).encode()
    if key not in _INERTIAS:
        if len(_INERTIAS) > 256:
            _INERTIAS.clear()
        _INERTIAS[key] = _apparent_inertias(model, links, samples, seed)
    return _INERTIAS[key].copy()


def _apparent_inertias(model: mujoco.MjModel, links: list[str], samples: int, seed: int) -> np.ndarray:
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    adr = [model.joint(name).qposadr[0] for name in links]
    full = np.zeros((model.nv, model.nv))
    best = np.full(model.nv, np.inf)
    for k in range(samples + 1):
        data.qpos[:] = model.qpos0
        if k and adr:
            data.qpos[adr] = rng.uniform(-np.pi, np.pi, len(adr))
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, full)
        best = np.minimum(best, 1.0 / np.diag(np.linalg.inv(full)))
    return best


def stable_timesteps(model: mujoco.MjModel, samples: int = STABILITY_SAMPLES) -> dict[str, tuple[float, str]]:
    """Per joint (``instance_params``' label): (largest stable timestep, the term that sets it)."""
    named = instance_params(model)
    links = [p.link_joint for _, p in named if p.link_joint != GROUND]
    inertia = apparent_inertias(model, links, samples)

    def at(name: str) -> float:
        # A side fixed to the world cannot move: it imposes no limit.
        return np.inf if name == GROUND else float(inertia[model.joint(name).dofadr[0]])

    return {name: stable_timestep(p, at(p.motor_joint), at(p.link_joint)) for name, p in named}


def check_model_stability(model: mujoco.MjModel, hint: str = "ArmSpec(timestep=...)") -> None:
    """Raise a one-line ValueError naming the instance, the term and the timestep it needs."""
    h = model.opt.timestep
    for name, (h_max, term) in stable_timesteps(model).items():
        if h > h_max:
            raise ValueError(f"{name}: {term} makes the joint too stiff for timestep={h:g} s: "
                             f"it needs timestep <= {h_max:.3g} s ({hint})")
