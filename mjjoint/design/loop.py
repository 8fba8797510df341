"""Closed-loop experiments: a link-angle reference for the controller of the recording.

Where the joint is run under its position controller, the experiment is a reference
trajectory theta_ref(t), not a torque: each rival is run in the loop (``rehearse.run_loop``,
the controller closing on the sensed angle) and the loop's command is the torque the windowed
predictions and the decision then work from, as for any recording. The command saturates at the
torque limit (the controller's ``u_max`` is lowered to it), so |u| <= max_torque holds by
construction here too; the loop keeps the link near the reference, so the excursion limit is
met by the reference's own range (the families' peak is the angle range), with the tracking
error checked on the runs like any limit.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np

from ..rehearse import Controller, Sensors, run_loop
from ..sim import Trace

# The loop's own sensors while designing: ideal, so that the run is the plant's (the lab's
# sensors are applied where a recording is simulated, ``record.logged``).
IDEAL = Sensors(resolver_bits=0, encoder_bits=0, torque_noise=0.0)


@dataclass(frozen=True)
class ClosedLoop:
    """The controller of the recording, its saturation capped at the experiment's torque limit."""

    controller: Controller

    def capped(self, max_torque: float) -> Controller:
        return replace(self.controller, u_max=min(self.controller.u_max, max_torque))

    def describe(self) -> dict:
        return self.controller.describe()


def loop_trace(model: mujoco.MjModel, reference: np.ndarray, controller: Controller, rate: float,
               gear_ratio: float) -> Trace:
    """The closed-loop run of ``model`` tracking the link-angle ``reference`` as a ``Trace``
    (velocities as the samples' central differences; no friction or internal-state logs)."""
    cols = run_loop(model, reference, controller, IDEAL, rate).columns
    n = len(cols["t"])
    zeros = np.zeros(n)
    return Trace(t=cols["t"], u=cols["u"], q=cols["q"], theta=cols["theta"],
                 qd=np.gradient(cols["q"], 1.0 / rate), thetad=np.gradient(cols["theta"], 1.0 / rate),
                 tau=cols["tau"], friction=zeros, load_friction=zeros, states=np.zeros((n, 0)),
                 gear_ratio=gear_ratio)
