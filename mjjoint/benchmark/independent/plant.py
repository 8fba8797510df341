"""The seed's elastic joint (Ruderman 2012, Sec. 2-3), written independently of mjjoint's
simulator: its own equations, integrated with a fixed-step classical Runge-Kutta (RK4) in
numpy, no MuJoCo, no mjjoint.physics or coupling kernel.

    motor   J q''  = u_e + c(q) - F(q, q', ...) - T / N                    (Eq. 4, 6)
    gear    delta = q/N - theta, de = dead_zone(delta, b), T = Gamma(de, ...) + D de'  (Eqs. 7, 16-18)
    link    J_L theta'' = T - m g l_h sin(theta) - F_L(theta') - R            (Eq. 9)
    rod     J_t phi'' = R - m g l_t sin(phi),  R = k_r (theta - phi) + d_r (theta' - phi')
            (a flexible rod as a hub and a tip inertia joined by a torsional spring: a lumped
            two-mass link, not the segmented rod of mjjoint's MJCF)

u_e is the commanded torque u through an optional first-order current loop (time constant
``current_lag``), c(q) an optional cogging torque, F the motor friction (``friction``), F_L
the load bearing's Coulomb (tanh-regularised) and viscous friction. The measured transmission
torque is T.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .friction import LuGre, MaxwellSlip, PositionDependence, TwoSEP
from .gear import BoucWenLaw, StopHysteresis, dead_zone

MAX_RATE_STEP = 0.5  # h times the bristle's relaxation rate (accuracy, well inside RK4's 2.78)
TWOSEP_SLOTS = 5


@dataclass(frozen=True)
class Cogging:
    amplitude: float     # [N m]
    per_rad: float       # spatial frequency in motor radians (any real number)
    phase: float = 0.0

    def torque(self, q: float) -> float:
        return self.amplitude * math.sin(self.per_rad * q + self.phase)


@dataclass(frozen=True)
class Rod:
    tip_inertia: float   # [kg m^2]
    stiffness: float     # [N m/rad]
    damping: float       # [N m s/rad]
    tip_gravity: float   # m g l of the tip part [N m]


@dataclass(frozen=True)
class JointPlant:
    gear_ratio: float
    motor_inertia: float
    link_inertia: float                 # hub (and rigid rod) [kg m^2]
    stiffness: float                    # k [N m/rad], link side
    damping: float                      # D [N m s/rad]
    gravity_moment: float               # m g l of the rigid link part [N m]
    load_coulomb: float = 0.0
    load_viscous: float = 0.0
    load_veps: float = 2e-3             # [rad/s] sign regularisation of the load's Coulomb friction
    friction: LuGre | MaxwellSlip | TwoSEP | None = None
    # LuGre's Coulomb level raised by this share of the motor-side gear torque |T| / N (tooth
    # and bearing friction pressed by the load: an efficiency below one)
    load_dependence: float = 0.0
    position_friction: PositionDependence | None = None
    cogging: Cogging | None = None
    current_lag: float = 0.0            # [s]
    backlash: float = 0.0               # total width [rad]
    hysteresis: BoucWenLaw | StopHysteresis | None = None
    rod: Rod | None = None

    # State layout: q, q', theta, theta', phi, phi', z (LuGre), x (Bouc-Wen), u_e, then the
    # friction law's own slots (the Maxwell elements; 2SEP's z1, z2, q_r and its memory of the
    # last reversal, Omega and the direction), then the hysteretic gear's sliders.
    @property
    def n_friction(self) -> int:
        if isinstance(self.friction, MaxwellSlip):
            return len(self.friction.stiffness)
        return TWOSEP_SLOTS if isinstance(self.friction, TwoSEP) else 0

    @property
    def n_sliders(self) -> int:
        return len(self.hysteresis.radii) if isinstance(self.hysteresis, StopHysteresis) else 0

    def initial_state(self, u0: float = 0.0) -> np.ndarray:
        s = np.zeros(9 + self.n_friction + self.n_sliders)
        s[8] = u0
        return s

    def transmission(self, s: np.ndarray) -> tuple[float, float, float]:
        """(T, de, de') at state s."""
        n = self.gear_ratio
        de = dead_zone(s[0] / n - s[2], self.backlash)
        if de == 0.0 and self.backlash > 0.0:
            return 0.0, 0.0, 0.0
        dde = s[1] / n - s[3]
        return self._spring(s, de, "torque") + self.damping * dde, de, dde

    def _spring(self, s: np.ndarray, de: float, what: str) -> float:
        """The gear spring's ``what``, "torque" or "stored" energy, at deflection de and state s:
        the hysteretic law's with its own state slots, else the linear spring's."""
        h = self.hysteresis
        if isinstance(h, BoucWenLaw):
            return getattr(h, what)(self.stiffness, de, s[7])
        if isinstance(h, StopHysteresis):
            return getattr(h, what)(de, s[9 + self.n_friction:])
        return self.stiffness * de if what == "torque" else 0.5 * self.stiffness * de ** 2

    def motor_friction(self, s: np.ndarray, t_gear: float) -> tuple[float, float, np.ndarray | None]:
        """(friction torque, dz/dt of LuGre, dz/dt of the Maxwell elements) at state s, the gear
        transmitting ``t_gear``."""
        f, v = self.friction, s[1]
        scale = 1.0 if self.position_friction is None else self.position_friction.factor(s[0])
        if isinstance(f, LuGre):
            level = f.fc * scale
            if self.load_dependence:
                level += self.load_dependence * abs(t_gear) / self.gear_ratio
            dz, torque = f.rates(v, s[6], level, self.motor_inertia)
            return torque, dz, None
        if isinstance(f, MaxwellSlip):
            z = s[9:9 + self.n_friction]
            return scale * f.spring(z) + f.sigma2 * v, 0.0, f.rates(v, z)
        if isinstance(f, TwoSEP):
            z1, z2, qr, omega = s[9:13]
            return f.force(v, z1, z2), 0.0, np.array([*f.rates(v, z1, z2, qr, omega), 0.0, 0.0])
        return 0.0, 0.0, None

    def derivative(self, s: np.ndarray, u: float) -> np.ndarray:
        d = np.zeros_like(s)
        t_gear, de, dde = self.transmission(s)
        fric, dz, dmax = self.motor_friction(s, t_gear)
        ue = s[8] if self.current_lag > 0 else u
        cog = 0.0 if self.cogging is None else self.cogging.torque(s[0])
        d[0] = s[1]
        d[1] = (ue + cog - fric - t_gear / self.gear_ratio) / self.motor_inertia
        load = self.load_coulomb * math.tanh(s[3] / self.load_veps) + self.load_viscous * s[3]
        rod_torque = 0.0
        if self.rod is not None:
            r = self.rod
            rod_torque = r.stiffness * (s[2] - s[4]) + r.damping * (s[3] - s[5])
            d[4] = s[5]
            d[5] = (rod_torque - r.tip_gravity * math.sin(s[4])) / r.tip_inertia
        d[2] = s[3]
        d[3] = (t_gear - self.gravity_moment * math.sin(s[2]) - load - rod_torque) / self.link_inertia
        d[6] = dz
        if isinstance(self.hysteresis, BoucWenLaw) and not (de == 0.0 and self.backlash > 0.0):
            d[7] = self.hysteresis.rate(dde, s[7])
        if self.current_lag > 0:
            d[8] = (u - s[8]) / self.current_lag
        if dmax is not None:
            d[9:9 + self.n_friction] = dmax
        if self.n_sliders:
            d[9 + self.n_friction:] = self.hysteresis.rates(dde, de, s[9 + self.n_friction:])
        return d

    def project(self, s: np.ndarray) -> np.ndarray:
        """Keep the rate-independent elements on their admissible sets after a step; 2SEP
        memorises Omega and restarts q_r and z2 where the motor's direction changed
        (``friction.TwoSEP``)."""
        if isinstance(self.friction, MaxwellSlip):
            s[9:9 + self.n_friction] = self.friction.clip(s[9:9 + self.n_friction])
        if isinstance(self.friction, TwoSEP) and s[1] != 0.0 and math.copysign(1.0, s[1]) != s[13]:
            s[12] = self.friction.reversal_memory(s[1], s[9], s[10])
            s[10:12] = 0.0
            s[13] = math.copysign(1.0, s[1])
        if self.n_sliders:
            de = dead_zone(s[0] / self.gear_ratio - s[2], self.backlash)
            s[9 + self.n_friction:] = self.hysteresis.clip(de, s[9 + self.n_friction:])
        return s

    def fast_rate(self, s: np.ndarray) -> float:
        """The friction state's fastest rate at state s [1/s] (LuGre's bristle relaxation
        s0 |v| / g; 2SEP's, ``TwoSEP.fast_rate``; 0 for the others), which sets the RK4 step
        (``simulate``)."""
        f = self.friction
        if isinstance(f, TwoSEP):  # its lag term B |w| z2 is a damper B |z2| on the rotor too
            return max(f.fast_rate(s[1], s[11]), f.b * abs(s[10]) / self.motor_inertia)
        if not isinstance(f, LuGre):
            return 0.0
        return abs(s[1]) / f.z0 * f.fc / min(f.fc, f.fs)

    def step(self, s: np.ndarray, u: float, h: float) -> np.ndarray:
        """One classical RK4 step of length h under a held input u."""
        k1 = self.derivative(s, u)
        k2 = self.derivative(s + 0.5 * h * k1, u)
        k3 = self.derivative(s + 0.5 * h * k2, u)
        k4 = self.derivative(s + h * k3, u)
        return self.project(s + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4))

    def energy(self, s: np.ndarray) -> float:
        """Kinetic, gravity and stored energy: the springs', the hysteretic gear's (``stored``)
        and the Maxwell elements'. Without input it can only fall."""
        t_spring = self._spring(s, dead_zone(s[0] / self.gear_ratio - s[2], self.backlash), "stored")
        e = 0.5 * self.motor_inertia * s[1] ** 2 + 0.5 * self.link_inertia * s[3] ** 2 + t_spring
        e += self.gravity_moment * (1 - math.cos(s[2]))
        if self.rod is not None:
            r = self.rod
            e += 0.5 * r.tip_inertia * s[5] ** 2 + 0.5 * r.stiffness * (s[2] - s[4]) ** 2
            e += r.tip_gravity * (1 - math.cos(s[4]))
        if isinstance(self.friction, MaxwellSlip):
            z = s[9:9 + self.n_friction]
            e += 0.5 * float(np.dot(self.friction.stiffness, z * z))
        return e


@dataclass
class Trajectory:
    t: np.ndarray
    states: np.ndarray      # (n, state)
    torque: np.ndarray      # transmission torque T at each sample
    u: np.ndarray = field(default_factory=lambda: np.zeros(0))


def simulate(plant: JointPlant, t: np.ndarray, input_at, substeps: int = 10, s0: np.ndarray | None = None
             ) -> Trajectory:
    """Integrate ``plant`` over the sample times ``t``; the input over [t_k, t_k+1) is
    ``input_at(k, state_k)`` (a controller may read the state it measures), held constant."""
    s = plant.initial_state() if s0 is None else np.array(s0, float)
    n = len(t)
    states = np.zeros((n, len(s)))
    torque = np.zeros(n)
    u = np.zeros(n)
    for k in range(n):
        states[k] = s
        torque[k] = plant.transmission(s)[0]
        if k == n - 1:
            u[k] = u[k - 1] if k else 0.0
            break
        u[k] = input_at(k, s)
        # RK4 is stable to h rate = 2.78: at least `substeps` steps, more while the bristle is fast.
        m = max(substeps, math.ceil((t[k + 1] - t[k]) * 1.5 * plant.fast_rate(s) / MAX_RATE_STEP))
        h = (t[k + 1] - t[k]) / m
        try:
            for _ in range(m):
                s = plant.step(s, u[k], h)
        except (ArithmeticError, ValueError):  # a state past math's domain: diverged within the sample
            s = np.full_like(s, np.nan)
        if not np.all(np.isfinite(s)):
            raise FloatingPointError(f"the independent plant diverged at t = {t[k + 1]:.4g} s (its RK4 steps "
                                     f"are sized at each sample's start: a sample of {t[k + 1] - t[k]:.3g} s "
                                     "may be too long for its fastest state)")
    return Trajectory(t, states, torque, u)
