"""Fig. 4: a mass on a spring to ground, kicked by a Dirac impulse at t = 1 s.

    (a) linear spring K with viscous damping D: decays to zero,
    (b) hysteretic spring (Bouc-Wen, mu small), no D: higher damping at first, then keeps
        oscillating, with no rest at zero,
    (c) hysteretic spring and the same D: settles, but at a non-zero deflection (memory).

The mass is the rotor of an ``mjjoint.joint`` with ``link_joint="world"``, so the plugin's
transmission (gear ratio 1) is the spring to ground and delta = q. The hysteretic spring
has the default k1 = 1e4 with ten times the default hardening (k3 = 1e9), x_u = 2 mrad,
mu = 0.1 and n = 2 (beta = gamma = 0.5 / x_u^2): with n = 2 the plastic loss of a cycle falls
off as amplitude^4, so small oscillations are barely damped by the hysteresis, the
"cancellation close to zero displacement" behind the chapter's limit cycle. The linear
stiffness of (a) is, as the chapter says, the average of the nonlinear map: the chord of the
hysteresis loop over the excited range +-``delta_ref`` (``restoring_loops.secant_stiffness``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..joint import JointParams
from ..params import check
from ..physics.boucwen import BoucWen
from ..physics.transmission import Transmission
from ..sim import Simulator
from . import plotting
from .models import compile_mjcf, inertia_body, mjcf
from .restoring_loops import secant_stiffness

X_U = 2e-3  # [rad] elastic-plastic transition of the Bouc-Wen state
HYSTERETIC = Transmission(gear_ratio=1.0, k1=1e4, k2=0.0, k3=1e9, damping=0.0,
                          hysteresis=BoucWen(mu=0.1, n=2.0, beta=0.5 / X_U ** 2, gamma=0.5 / X_U ** 2))
CASES = ("linear + D", "hysteretic", "hysteretic + D")
FIGURE = "fig4_hysteretic_spring.png"


@dataclass(frozen=True)
class SpringExample:
    mass: float = 25.0         # [kg m^2]: ~6 Hz with the ~1e4 N m/rad loop chord
    damping: float = 100.0     # D [N m s/rad]: 8 % of critical on the linear spring
    impulse: float = 4.0       # [N m s] at t_impulse: ~6 mrad first swing, 3 x_u
    delta_ref: float = 6e-3    # [rad] range over which the linear K averages the map
    t_impulse: float = 1.0     # [s]

    def __post_init__(self) -> None:
        check("mass", self.mass, 0.0, lo_open=True)
        check("damping", self.damping, 0.0, lo_open=True)
        check("impulse", self.impulse, 0.0, lo_open=True)
        check("delta_ref", self.delta_ref, 0.0, lo_open=True)
        check("t_impulse", self.t_impulse, 0.0)

    def transmissions(self, hysteretic: Transmission = HYSTERETIC) -> tuple[Transmission, ...]:
        """The springs of cases (a), (b), (c)."""
        k_lin = secant_stiffness(hysteretic, self.delta_ref)
        linear = Transmission(gear_ratio=1.0, k1=k_lin, k2=0.0, k3=0.0, damping=self.damping, hysteresis=None)
        return linear, replace(hysteretic, damping=0.0), replace(hysteretic, damping=self.damping)


def spring_model(example: SpringExample, transmission: Transmission, timestep: float = 1e-4):
    params = JointParams(motor_joint="motor", link_joint="world", friction=None,
                         transmission=transmission, load_friction=None)
    return compile_mjcf(mjcf("mass on a spring to ground", timestep,
                             inertia_body("mass", "motor", example.mass), "motor", params))


@dataclass
class Fig4Data:
    example: SpringExample
    k_linear: float
    t: np.ndarray
    delta: np.ndarray      # (3, n) deflection [rad] of cases (a), (b), (c)
    velocity: np.ndarray   # (3, n) [rad/s]
    x: np.ndarray          # (3, n) Bouc-Wen state (0 for the linear spring)


def compute(example: SpringExample = SpringExample(), duration: float = 8.0, sample_rate: float = 1000.0,
            hysteretic: Transmission = HYSTERETIC) -> Fig4Data:
    n = round(duration * sample_rate)
    u = np.zeros(n)
    u[round(example.t_impulse * sample_rate)] = example.impulse * sample_rate  # one-sample Dirac
    springs = example.transmissions(hysteretic)
    traces = [Simulator(spring_model(example, tr), sample_rate=sample_rate).run(u) for tr in springs]
    return Fig4Data(example, springs[0].k1, traces[0].t, np.array([tr.delta for tr in traces]),
                    np.array([tr.qd for tr in traces]), np.array([tr.state("x") for tr in traces]))


def draw(data: Fig4Data, path: str | Path) -> Path:
    fig, axes = plotting.figure(3, 1, height=8.0, sharex=True)
    for i, (ax, name, d) in enumerate(zip(axes, CASES, data.delta)):
        ax.plot(data.t, 1e3 * d, color=plotting.COLORS[i])
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set(ylabel=r"$\delta$ [mrad]", title=f"({'abc'[i]}) {name}")
    axes[0].set_title(f"(a) linear spring K = {data.k_linear:.3g} N m/rad (loop chord) + D")
    axes[-1].set_xlabel("t [s]")
    return plotting.save(fig, path)


def write(out: str | Path) -> list[Path]:
    """Compute with the defaults and draw Fig. 4 into folder ``out``."""
    return [draw(compute(), Path(out) / FIGURE)]
