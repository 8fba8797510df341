"""Memory layouts shared by the Python side and the numba callbacks, derived from the terms
(``physics.catalogue``).

``BLOCK``: the per-instance float64 parameter block (a ``registry`` row, which
``d->plugin_data[instance]`` caches), built once per model from the instance's MJCF config:
the joint addresses, then each term's slots (its kind, then its fields: ``Term.block_values``).
``STATE``: the instance's slice of ``d->plugin_state``, i.e. the internal states MuJoCo saves,
restores, resets and rolls out: each term's states, then the integrator's memory.
The kernels read both through the namedtuples below, which numba takes as constants.
"""
from __future__ import annotations

from collections import namedtuple
from itertools import accumulate

import numpy as np

from ..physics.catalogue import BY_SECTION, TERMS

# Parameter block: the joint addresses (qpos and dof of the motor and link joints; -1: world),
# the number of joints the instance drives (joint.JOINTS_KEY; the blocks of its joints follow
# each other in its registry row) and whether any additive term is present (1.0; 0.0 lets the
# kernels skip them all at once).
MQ, MD, LQ, LD, NJ, ANY_SITE = range(6)
MAX_JOINTS = 8  # joints one instance may drive
# Each term's first slot (its kind, then its fields) and first state, in catalogue order.
_starts = dict(zip(BY_SECTION, accumulate((1 + len(t.fields) for t in TERMS), initial=ANY_SITE + 1)))
_state_starts = dict(zip(BY_SECTION, accumulate((len(t.states) for t in TERMS), initial=0)))
BLOCK_LEN = ANY_SITE + 1 + sum(1 + len(t.fields) for t in TERMS)


def section(name: str):
    """Absolute block slots of a term: ``kind`` and each field."""
    t = BY_SECTION[name]
    o = _starts[name]
    return namedtuple(f"{name}_slots", ("kind",) + t.fields)(o, *(o + i for i in t.offsets))


FRICTION, TRANSMISSION, HYSTERESIS = section("friction"), section("transmission"), section("hysteresis")
LOAD = section("load_friction")
FRICTION_2SEP = BY_SECTION["friction"].kind_code("2sep")
FRICTION_STATIC = BY_SECTION["friction"].kind_code("static")

# Plugin state: the terms' states, then the time they hold at (NaN: at whatever time they are
# next evaluated; kernels.joint_catch_up), then the integrator's memory: the motor's velocity
# and the joint's torque on it at the last evaluation and the other torques on it that the
# step since implies (kernels.implicit_dof), the link's velocity and the transmission torque at
# the last evaluation and the other torques on the deflection (kernels.stiffness_limit), the
# joint's torque on the link at the last evaluation and the other torques on the link dof, the
# last step's and the one's before, which the bearing's step extrapolates (kernels.bearing).
# NaN: unknown, after a reset or for states set by hand. Last, whether the rotor was substepped
# over the step just evaluated (1; kernels.rotor) and the 2SEP states where that ended
# (z1, z2, omega, q_r, w_sign), which the step's advance takes.
STATE_NAMES = tuple(s for t in TERMS for s in t.states)  # the physical ones, before AT
Z1, Z2, OMEGA, QR, WSIGN = (STATE_NAMES.index(s) for s in BY_SECTION["friction"].states)
X = STATE_NAMES.index("x")
AT, WP, FP, FO, WPL, TP, FOT, FPL, FOL, FOL2, SUB = range(len(STATE_NAMES), len(STATE_NAMES) + 11)
NSTATE = len(STATE_NAMES) + 16  # SUB and the five after it

# The additive terms, as the kernels call them: (torque kernel, first block slot, first state).
SITE_TERMS = tuple((t.torque, _starts[t.section], _state_starts[t.section]) for t in TERMS if t.torque is not None)
ADVANCE_TERMS = tuple((t.advance, _starts[t.section], _state_starts[t.section])
                      for t in TERMS if t.advance is not None)


def pack(params, motor_qpos: int, motor_dof: int, link_qpos: int, link_dof: int, njoint: int = 1) -> np.ndarray:
    """The parameter block of one joint for ``JointParams`` ``params``, one of ``njoint`` its
    plugin instance drives."""
    b = np.zeros(BLOCK_LEN)
    b[[MQ, MD, LQ, LD, NJ]] = motor_qpos, motor_dof, link_qpos, link_dof, njoint
    b[ANY_SITE] = float(any(params.term(t.section) is not None for t in TERMS if t.torque is not None))
    for t in TERMS:
        o = _starts[t.section]
        b[o:o + 1 + len(t.fields)] = t.block_values(params.term(t.section))
    return b


def steady_states(params, motion: dict[str, np.ndarray]) -> np.ndarray:
    """Plugin states (n, NSTATE) on the steady branch of the measured ``motion`` (arrays (n,) q,
    w, theta, wtheta, delta: ``Term.steady``), 0 for a term without ``steady``, held at
    whatever time they are next evaluated (AT NaN)."""
    st = np.zeros((len(motion["w"]), NSTATE))
    st[:, AT] = np.nan
    for t in TERMS:
        p = params.term(t.section)
        if t.steady is not None and p is not None:
            for name, values in t.steady(p, motion).items():
                st[:, STATE_NAMES.index(name)] = values
    return st


def term_states(section: str) -> slice:
    """The plugin-state slots of a term's states."""
    return slice(_state_starts[section], _state_starts[section] + len(BY_SECTION[section].states))


def term_slots(section: str) -> slice:
    """The parameter-block slots of a term: its kind, then its fields."""
    return slice(_starts[section], _starts[section] + 1 + len(BY_SECTION[section].fields))
