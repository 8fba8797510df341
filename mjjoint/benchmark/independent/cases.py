"""Out-of-regime cases: truths of the independent plant drawn from ranges and structures the
development set (``benchmark.cases``: the lab arm, 2SEP, the lab programme) does not use.

Each case names the effects the tool is given as its base (the truth's catalogued physics, as in
the development set), which names count as the right answer (``right``: the catalogue's form of
the hidden physics; empty where the catalogue has none), and which further names are no false
addition because they are catalogue forms of the truth's base physics (``tolerated``: LuGre's
pre-sliding is what 2SEP models, and every plant's friction holds its rotor at rest, as the
exact sign does). Parameters are drawn per seed within each case's range.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .friction import LuGre, MaxwellSlip, PositionDependence, TwoSEP
from .gear import BoucWenLaw, StopHysteresis
from .plant import Cogging, JointPlant, Rod
from .record import Excitation, Sensors

BASE = ("coulomb_friction", "viscous_friction", "load_friction", "gravity", "linear_stiffness",
        "transmission_damping")
# Every plant's friction holds its rotor at rest below break-away (LuGre's bristles, the
# Maxwell-slip elements, 2SEP's pre-sliding spring): the catalogue's form of that is the exact sign.
HOLDS = ("sticking_friction",)
LUGRE_FORMS = ("dynamic_friction", *HOLDS)   # catalogue forms of LuGre's pre-sliding and lag, and its hold
# A current loop's first-order lag: the catalogue's own lag, or the dead time of the same shift.
LAG = ("input_lag", "input_delay")
# The smallest link inertia the tool's arm model can take (hub + bare rod, no tip mass) [kg m^2].
MIN_LINK_INERTIA = 0.03


@dataclass(frozen=True)
class OutsideCase:
    name: str
    seed: int
    what: str                       # the hidden physics, in words
    plant: JointPlant
    sensors: Sensors
    excitation: Excitation
    base: tuple[str, ...] = BASE
    right: tuple[str, ...] = ()     # names that are the right answer (empty: none catalogued)
    tolerated: tuple[str, ...] = LUGRE_FORMS

    @property
    def hidden(self) -> bool:
        """Whether the truth has physics beyond the base (or the sensors beyond the lab's)."""
        return self.name not in CONTROLS

    def true_noise(self) -> dict[str, float]:
        """The recorded signals' true noise std (quantisation step / sqrt 12, white noise)."""
        s, n = self.sensors, self.plant.gear_ratio
        q = math.hypot(2 * math.pi / 2 ** s.motor_bits / math.sqrt(12), s.motor_noise)
        th = 2 * math.pi / 2 ** s.link_bits / math.sqrt(12)
        return {"q": q, "theta": th, "delta": math.hypot(q / n, th), "tau": s.torque_noise}


def _lab(r: np.random.Generator, **over) -> JointPlant:
    """A joint of the lab's size with parameters off the development set's (gear 100-120, stiffer
    or softer gear, a heavier link, LuGre friction)."""
    n = float(r.choice([100.0, 120.0]))
    fc = r.uniform(0.03, 0.06)
    values = dict(gear_ratio=n, motor_inertia=r.uniform(6e-5, 1.2e-4), link_inertia=r.uniform(0.12, 0.3),
                  stiffness=r.uniform(2500, 9000), damping=r.uniform(1.0, 3.0),
                  gravity_moment=r.uniform(2.5, 6.0), load_coulomb=r.uniform(0.2, 0.5),
                  load_viscous=r.uniform(0.02, 0.08),
                  friction=LuGre(fc=fc, fs=fc, vs=1.0, sigma2=r.uniform(1e-4, 4e-4)))
    values.update(over)
    return JointPlant(**values)


def _with(p: JointPlant, **over) -> JointPlant:
    return dataclasses.replace(p, **over)


def _control(r):
    return _lab(r), {}


def _backlash(r):
    return _lab(r, backlash=r.uniform(7e-4, 1.5e-3)), {"right": ("backlash",)}


def _boucwen(r):
    x_u = r.uniform(4e-3, 8e-3)   # the development set's 1-3 mrad
    return _lab(r, hysteresis=BoucWenLaw(mu=r.uniform(0.6, 0.8), beta=1 / x_u)), \
        {"right": ("transmission_hysteresis",)}


def _prandtl_gear(r):
    p = _lab(r)
    radii = tuple(np.array([0.5, 1.5, 3.0]) * r.uniform(1e-3, 2e-3))
    share = r.uniform(0.3, 0.5)
    weights = tuple(np.full(3, share * p.stiffness / 3))
    return _with(p, hysteresis=StopHysteresis(elastic=(1 - share) * p.stiffness, radii=radii, weights=weights)), \
        {"right": ("transmission_hysteresis",)}


def _cogging(r):
    p = _lab(r)
    return _with(p, cogging=Cogging(amplitude=r.uniform(0.02, 0.04), per_rad=r.uniform(2.3, 7.7),
                                    phase=r.uniform(-math.pi, math.pi))), \
        {"right": ("torque_ripple", "motor_periodic_q")}  # the catalogue's ripple, or the generic form at a real period


def _position_friction(r):
    p = _lab(r)
    # the generic form of this very structure: a friction level periodic in the motor angle
    return _with(p, position_friction=PositionDependence(amplitude=r.uniform(0.3, 0.5), per_rad=r.uniform(0.3, 0.8),
                                                         phase=r.uniform(-math.pi, math.pi))), \
        {"right": ("motor_friction_periodic_q",)}


def _maxwell(r):
    p = _lab(r)
    fc = p.friction.fc
    slip = tuple(fc * np.array([0.4, 0.3, 0.2, 0.1]))
    stiffness = tuple(np.array(slip) / (np.array([0.5, 1.5, 4.0, 10.0]) * r.uniform(1e-3, 3e-3)))
    return _with(p, friction=MaxwellSlip(stiffness=stiffness, slip=slip, sigma2=p.friction.sigma2)), \
        {"right": ("dynamic_friction",), "tolerated": HOLDS}


def _twosep(r):
    """The seed's 2SEP friction read from the chapter alone (``friction.TwoSEP``), a Stribeck dip
    and lag gains beyond the development set's (K 500-2000, B 20-100)."""
    fc = r.uniform(0.03, 0.06)
    f = TwoSEP(fc=fc, fs=fc * r.uniform(1.3, 1.8), vs=r.uniform(0.3, 1.0), sigma2=r.uniform(1e-4, 4e-4),
               k=r.uniform(2000, 5000), b=r.uniform(100, 300))
    return _lab(r, friction=f), {"right": ("dynamic_friction", "stribeck_friction"), "tolerated": HOLDS}


def _seed_joint(r):
    """The chapter's joint: 2SEP friction on the motor and a Bouc-Wen gear, both written here."""
    p, truth = _twosep(r)
    return _with(p, hysteresis=BoucWenLaw(mu=r.uniform(0.6, 0.8), beta=1 / r.uniform(4e-3, 8e-3))), \
        {**truth, "right": (*truth["right"], "transmission_hysteresis")}


def _current_loop(r):
    return _lab(r, current_lag=r.uniform(2e-3, 5e-3)), {"right": LAG}


def _gear_efficiency(r):
    return _lab(r, load_dependence=r.uniform(0.2, 0.4)), {"right": ("load_dependent_friction",)}


def _coarse_encoder(r):
    return _lab(r), {"sensors": Sensors(motor_bits=11, motor_noise=2e-4)}


def _small_motor(r):
    fc = r.uniform(0.02, 0.04)
    p = JointPlant(gear_ratio=50.0, motor_inertia=r.uniform(8e-5, 1.5e-4), link_inertia=r.uniform(0.035, 0.06),
                   stiffness=r.uniform(300, 600), damping=r.uniform(0.05, 0.15), gravity_moment=r.uniform(0.3, 0.6),
                   load_coulomb=r.uniform(0.02, 0.05), load_viscous=r.uniform(2e-3, 6e-3),
                   friction=LuGre(fc=fc, fs=fc, vs=1.0, sigma2=r.uniform(5e-5, 1.5e-4), z0=0.02),
                   hysteresis=BoucWenLaw(mu=r.uniform(0.5, 0.7), beta=1 / r.uniform(5e-3, 1e-2)))
    return p, {"right": ("transmission_hysteresis",), "sensors": Sensors(motor_bits=12, link_bits=16, torque_noise=0.005)}


def _big_axis(r):
    fc = r.uniform(1.5, 3.0)
    p = JointPlant(gear_ratio=120.0, motor_inertia=r.uniform(5e-3, 1e-2), link_inertia=r.uniform(20, 40),
                   stiffness=r.uniform(1e5, 3e5), damping=r.uniform(150, 300), gravity_moment=r.uniform(200, 400),
                   load_coulomb=r.uniform(20, 40), load_viscous=r.uniform(5, 15),
                   friction=LuGre(fc=fc, fs=fc, vs=1.0, sigma2=r.uniform(0.01, 0.03), z0=0.02),
                   backlash=r.uniform(2e-4, 4e-4))
    return p, {"right": ("backlash",), "sensors": Sensors(torque_noise=2.0), "sweep": 0.25}


def _flexible_rod(r):
    p = _lab(r)
    share = r.uniform(0.6, 0.8)       # of the link inertia at the rod's tip
    tip = share * p.link_inertia
    f_rod = r.uniform(8.0, 14.0)      # the rod's first mode with the hub held [Hz]
    rod = Rod(tip_inertia=tip, stiffness=tip * (2 * math.pi * f_rod) ** 2, damping=0.02 * 2 * tip * 2 * math.pi * f_rod,
              tip_gravity=0.8 * p.gravity_moment)
    return _with(p, link_inertia=p.link_inertia - tip, gravity_moment=0.2 * p.gravity_moment, rod=rod), \
        {"right": ("link_flexibility",)}


def _backlash_and_lag(r):
    return _lab(r, backlash=r.uniform(7e-4, 1.5e-3), current_lag=r.uniform(2e-3, 5e-3)), \
        {"right": ("backlash", *LAG)}


def _position_friction_and_hysteresis(r):
    p, truth = _position_friction(r)
    return _with(p, hysteresis=BoucWenLaw(mu=r.uniform(0.6, 0.8), beta=1 / r.uniform(4e-3, 8e-3))), \
        {"right": ("transmission_hysteresis", *truth["right"])}


def _link_skew(r):
    return _lab(r), {"right": ("sensor_skew",), "sensors": Sensors(link_skew=r.uniform(1e-3, 3e-3))}


def _torque_filter(r):
    return _lab(r), {"right": ("torque_skew",), "sensors": Sensors(torque_filter=r.uniform(5e-4, 2e-3))}


CASES: dict[str, tuple[str, Callable]] = {
    "control": ("nothing beyond the base: LuGre friction, linear gear", _control),
    "coarse_encoder": ("nothing beyond the base; 11-bit motor encoder with noise", _coarse_encoder),
    "backlash_wide": ("backlash 0.7-1.5 mrad", _backlash),
    "boucwen_soft": ("Bouc-Wen gear, elastic share 0.6-0.8, x_u 4-8 mrad", _boucwen),
    "prandtl_gear": ("Prandtl-Ishlinskii gear hysteresis (three elastic-plastic elements)", _prandtl_gear),
    "cogging": ("cogging torque at a non-integer period, 2.3-7.7 per motor radian", _cogging),
    "position_friction": ("Coulomb level varying 30-50 % with the motor angle (a generic form's structure)",
                          _position_friction),
    "maxwell_slip": ("4-element Maxwell-slip friction instead of LuGre", _maxwell),
    "current_loop": ("current loop as a 2-5 ms first-order lag", _current_loop),
    "small_motor": ("small servo (J ~1e-4, Fc ~0.03, N 50) with a Bouc-Wen gear", _small_motor),
    "big_axis": ("big axis (J ~1e-2, link 20-40 kg m^2, k ~2e5) with backlash", _big_axis),
    "flexible_rod": ("lumped two-mass flexible rod, 8-14 Hz", _flexible_rod),
    "backlash+lag": ("backlash and a current-loop lag", _backlash_and_lag),
    "posfriction+hysteresis": ("position-dependent friction and a Bouc-Wen gear", _position_friction_and_hysteresis),
    "gear_efficiency": ("friction level raised by 20-40 % of the motor-side gear torque", _gear_efficiency),
    # appended: a case's draws are seeded by its place in this table
    "twosep": ("2SEP friction read from the chapter alone (z2 restarted at reversals), K 2000-5000, B 100-300",
               _twosep),
    "seed_joint": ("the chapter's joint: that 2SEP and a Bouc-Wen gear", _seed_joint),
    "link_skew": ("the link encoder read 1-3 ms late (a timing skew between the encoders)", _link_skew),
    "torque_filter": ("the torque cell behind a first-order low-pass, 0.5-2 ms", _torque_filter),
}
CONTROLS = ("control", "coarse_encoder")


def make_case(name: str, seed: int, duration: float = 6.0, rate: float = Excitation.rate,
              program: str = Excitation.program) -> OutsideCase:
    """Case ``name``'s truth drawn for ``seed``, recorded for ``duration`` [s] at ``rate`` [Hz] (the
    PD loop runs at the sample rate) under the excitation ``program``."""
    if name not in CASES:
        raise ValueError(f"unknown out-of-regime case {name!r} (allowed: {', '.join(CASES)})")
    if not rate > 0:
        raise ValueError(f"sample rate {rate!r} Hz out of range (allowed: > 0)")
    what, build = CASES[name]
    r = np.random.default_rng(7000 + 97 * seed + list(CASES).index(name))
    plant, extra = build(r)
    assert plant.link_inertia + (plant.rod.tip_inertia if plant.rod else 0) >= MIN_LINK_INERTIA
    sensors = extra.pop("sensors", Sensors())
    excitation = Excitation(duration=duration, rate=rate, seed=seed, sweep=extra.pop("sweep", Excitation.sweep),
                            program=program)
    return OutsideCase(name, seed, what, plant, sensors, excitation, **extra)
