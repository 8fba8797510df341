"""Sec. 4, the fourth FRF of Fig. 11: motor velocity per joint torque, W/T, after a load shock.

The chapter strikes the load side mechanically and divides the motor velocity by the torque
cell's joint torque. Here a torque pulse of the impulse's 1.5 ms acts on the output hinge (a
motor actuator on joint ``link`` added to the arm's MjSpec, which the plugin does not know
of), and T is the transmission torque tau. The motor feels only -T/N and its own friction,

    J q'' + F(q') = u - T/N   (u = 0)   =>   W/T = -1/(N (J s + F'))  where F is linear,

so W/T is the rotor's admittance seen through the gear whatever the load does: N |W/T|
lies on the same rotor mass line as the free W/U once friction no longer holds the motor.
The reference of this FRF is the response T, so the bins masked are those where T has (near)
no energy (T's roll-off) and those where the applied pulse has none (its zero at 667 Hz).
"""
from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ..assets.builder import ArmSpec, build_arm, load_model
from ..excitation import Impulse
from ..joint import JointParams
from ..sim import Simulator, Trace, held_controls
from .signals import excited, impulse_frf

# [N m] on the output hinge for 1.5 ms: T peaks near 75 N m, T/N = 0.47 N m slides the motor
# well past its 0.12 N m break-away, as the chapter's W/T (like the free W/U) shows.
SHOCK_TORQUE = 50.0
SHOCK_ACTUATOR = "shock"
# T is itself a response, peaked at the joint modes, so its floor sits lower than a pulse's
# (signals.INPUT_FLOOR): 1 % of its peak keeps its broadband part and masks where it has next
# to nothing (the pulse's zero at 667 Hz; T's roll-off above the modes of a rigid link).
TORQUE_FLOOR = 0.01


class ShockedArm(Simulator):
    """The arm with a torque motor on the output hinge; ``run`` takes (n, 2) inputs:
    column 0 the motor torque u, column 1 the load-side torque [N m]."""

    def __init__(self, arm: ArmSpec = ArmSpec(), joint: JointParams = JointParams(), sample_rate: float = 1000.0):
        spec = build_arm(arm, joint)
        act = spec.add_actuator(name=SHOCK_ACTUATOR, target=joint.link_joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_motor()
        super().__init__(load_model(spec), sample_rate=sample_rate)
        self.shock = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_ACTUATOR, SHOCK_ACTUATOR)

    def controls(self, u: np.ndarray, before=0.0) -> np.ndarray:
        u = np.asarray(u, float)
        if u.ndim != 2 or u.shape[1] != 2:
            raise ValueError(f"u must be (n, 2): motor torque and load-side torque, got shape {u.shape}")
        motor, shock = np.broadcast_to(before, (2,))
        ctrl = super().controls(u[:, 0], motor)
        ctrl[:, self.shock] = held_controls(u[:, 1], self.substeps, shock)
        return ctrl


@dataclass
class ShockData:
    f: np.ndarray
    frf: np.ndarray        # W/T (complex), NaN where T has no energy
    trace: Trace
    shock: np.ndarray      # applied load-side torque record [N m]


def shock_frf(arm: ArmSpec, joint: JointParams, sample_rate: float, duration: float, t0: float,
              width: float, amplitude: float = SHOCK_TORQUE) -> ShockData:
    """Strike the output with ``amplitude`` for ``width`` at ``t0``; W/T from the free arm's records."""
    sim = ShockedArm(arm, joint, sample_rate)
    p = Impulse(amplitude=amplitude, t0=t0, width=width).sample(sample_rate, duration)
    tr = sim.run(np.column_stack([np.zeros_like(p), p]))
    f, h = impulse_frf(tr.tau, tr.qd, sample_rate, floor=TORQUE_FLOOR)
    h[~excited(p)] = np.nan  # what T holds where the pulse has no energy is not its response
    return ShockData(f, h, tr, p)
