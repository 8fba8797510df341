"""MuJoCo stages a windowed prediction does not need, switched off in the models it rolls out.

A prediction reads the states a rollout returns, never its sensors, and the plants built for
identification collide nothing and carry no limits, equalities or dry friction of MuJoCo's own
(the joint physics is the plugin's, applied in the passive stage). MuJoCo still runs its sensor
stage, collision detection and constraint pipeline every step: a fifth of the wall time of the
20 s backlash diagnosis (docs/benchmark.md, "Speed of identification"). Switching them off
changes no state bit (``tests/test_stages.py``): with no constraint, MuJoCo's acceleration is
its unconstrained one either way. A model that can make a constraint (a user's arm with joint
limits or colliding geoms) keeps those stages.
"""
from __future__ import annotations

import mujoco
import numpy as np

_SENSOR = int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
_CONSTRAINTS = int(mujoco.mjtDisableBit.mjDSBL_CONSTRAINT) | int(mujoco.mjtDisableBit.mjDSBL_CONTACT)


def can_constrain(model: mujoco.MjModel) -> bool:
    """Whether any element of ``model`` can produce a constraint row: an equality, a limited or
    dry-friction joint or tendon, a geom pair that may touch, a flex."""
    return bool(model.neq or model.npair or model.nflex
                or np.any(model.jnt_limited) or np.any(model.dof_frictionloss > 0)
                or np.any(model.tendon_limited) or np.any(model.tendon_frictionloss > 0)
                or np.any(model.geom_contype) or np.any(model.geom_conaffinity))


def for_prediction(model: mujoco.MjModel) -> mujoco.MjModel:
    """``model`` with the stages a prediction does not read switched off, in place."""
    model.opt.disableflags |= _SENSOR if can_constrain(model) else _SENSOR | _CONSTRAINTS
    return model
