"""Fig. 6: link vibrations of the joint load (Eq. 10) under a lagged torque step.

Eq. (10) is the load of Fig. 5 (a): the gear output of inertia M (hub) carries, through a
link spring k and damper d, a concentrated link mass L; theta is the output angle, theta_L the
link's and alpha = theta - theta_L the link deflection. Its linear part, with gravity and the
bearing's Coulomb term dropped as in the chapter's example, is

    M theta''   = tau - d_f theta' - k alpha - d alpha'
    L theta_L'' =                    k alpha + d alpha'

This is pure multibody physics, so the model is a dedicated MJCF with MuJoCo doing all of
it: the hub on hinge "link" (inertia M, native damping d_f: the bearing's viscous term), the
link body on hinge "flex" *relative* to the hub (inertia L about the same axis, stiffness k,
damping d). The relative angle is flex = theta_L - theta = -alpha, and the kinetic energy
M theta'^2/2 + L (theta' + flex')^2/2 is exactly Eq. (10)'s. It is the arm's hub with one
flexible segment (``ArmSpec(segments=1)``) with the segment's mass lumped at the axis, and the
torque applied to the hub directly: the chapter replaces the actuator and gear by the lag.

Chapter's ratios: M/L = 0.1, d_f/d = 1e4, stiffnesses 1k and 10k; here M = 0.1 and
L = 1 kg m^2, d_f = 1 and d = 1e-4 N m s/rad, k = 1e3 and 1e4 N m/rad. The 1 N m step passes
a first-order lag of 1000 rad/s (applied to the sampled input before it is fed). The free-free link modes sit at sqrt(k (1/M + 1/L)) = 105 and 332 rad/s, well under
the lag's corner, so the deflection amplitude scales ~1/k.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..params import check
from . import plotting
from .models import compile_mjcf, inertia_body, mjcf, rollout
from .signals import first_order_lag

STIFFNESSES = (1e3, 1e4)
LAG_CUTOFF = 1000.0  # [rad/s]
FIGURE = "fig6_link_vibration.png"


@dataclass(frozen=True)
class LinkLoad:
    """Parameters of Eq. (10) without gravity and Coulomb friction."""

    hub_inertia: float = 0.1       # M [kg m^2]
    link_inertia: float = 1.0      # L [kg m^2]
    bearing_damping: float = 1.0   # d_f [N m s/rad]
    link_damping: float = 1e-4     # d [N m s/rad]

    def __post_init__(self) -> None:
        check("hub_inertia", self.hub_inertia, 0.0, lo_open=True)
        check("link_inertia", self.link_inertia, 0.0, lo_open=True)
        check("bearing_damping", self.bearing_damping, 0.0)
        check("link_damping", self.link_damping, 0.0)


def load_model(load: LinkLoad, stiffness: float, timestep: float = 5e-5):
    check("stiffness", stiffness, 0.0, lo_open=True)
    link = inertia_body("link_mass", "flex", load.link_inertia, stiffness=stiffness, damping=load.link_damping)
    hub = inertia_body("hub", "link", load.hub_inertia, inner=link, damping=load.bearing_damping)
    return compile_mjcf(mjcf(f"joint load, Eq. 10, k={stiffness:g}", timestep, hub, "link"))


@dataclass
class Fig6Data:
    load: LinkLoad
    stiffnesses: tuple[float, ...]
    t: np.ndarray
    tau: np.ndarray        # lagged torque step [N m]
    theta_d: np.ndarray    # (len(stiffnesses), n) output velocity [rad/s]
    link_d: np.ndarray     # (len(stiffnesses), n) link velocity theta_L' [rad/s]
    alpha: np.ndarray      # (len(stiffnesses), n) link deflection theta - theta_L [rad]

    @property
    def amplitudes(self) -> np.ndarray:
        """Largest link deflection of each stiffness [rad]."""
        return np.abs(self.alpha).max(axis=1)


def compute(load: LinkLoad = LinkLoad(), stiffnesses: tuple[float, ...] = STIFFNESSES, step: float = 1.0,
            duration: float = 0.5, t_step: float = 0.02, sample_rate: float = 10000.0) -> Fig6Data:
    n = round(duration * sample_rate)
    t = np.arange(n) / sample_rate
    tau = first_order_lag(np.where(t >= t_step, step, 0.0), LAG_CUTOFF, sample_rate)
    th, tl, al = [], [], []
    for k in stiffnesses:
        s = rollout(load_model(load, k), tau, sample_rate)
        th.append(s.qvel[:, 0])
        tl.append(s.qvel[:, 0] + s.qvel[:, 1])
        al.append(-s.qpos[:, 1])
    return Fig6Data(load, tuple(stiffnesses), t, tau, np.array(th), np.array(tl), np.array(al))


def draw(data: Fig6Data, path: str | Path) -> Path:
    fig, axes = plotting.figure(1 + len(data.stiffnesses), 1, height=3.0 * (1 + len(data.stiffnesses)), sharex=True)
    ax = axes[0]
    ax.plot(data.t, data.theta_d[0], color=plotting.COLORS[0], label=r"$\dot\theta$ (output)")
    ax.plot(data.t, data.link_d[0], color=plotting.COLORS[1], label=r"$\dot\theta_L$ (link)")
    ax.set(ylabel="velocity [rad/s]", title=f"(a) velocities, k = {data.stiffnesses[0]:g} N m/rad")
    ax.legend(loc="lower right")
    for i, (ax, k, a) in enumerate(zip(axes[1:], data.stiffnesses, data.alpha)):
        ax.plot(data.t, 1e3 * a, color=plotting.COLORS[i + 2])
        ax.set(ylabel=r"$\alpha$ [mrad]", title=f"({'bcdef'[i]}) link deflection, k = {k:g} N m/rad")
    axes[-1].set_xlabel("t [s]")
    return plotting.save(fig, path)


def write(out: str | Path) -> list[Path]:
    """Compute with the defaults and draw Fig. 6 into folder ``out``."""
    return [draw(compute(), Path(out) / FIGURE)]
