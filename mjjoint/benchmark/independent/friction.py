"""Motor friction laws of the independent plant, written from their papers, not from mjjoint.physics.

* LuGre (Canudas de Wit et al. 1995): a bristle state z, dz/dt = v - sigma0 |v| z / g(v),
  F = sigma0 z + sigma1 dz/dt + sigma2 v, with the Stribeck curve g(v) = Fc + (Fs - Fc)
  exp(-(v/vs)^2). Its steady state is the Stribeck map plus viscous friction; its bristle
  gives pre-sliding. The seed joint's 2SEP (Eqs. 11-15) has the same steady state.
* Generalised Maxwell-slip (Lampaert et al. 2003): parallel elastoplastic elements, each a
  spring k_i that slips at F_i; a multi-element pre-sliding hysteresis that no catalogued term
  has (2SEP's is one exponential branch).
* 2SEP (Ruderman 2012, Eqs. 11-15, read literally): F = z1 + B |w| z2, z1' = |Omega| w K
  exp(-K q_r) with Omega = sgn(w) Fc - F and q_r = 0 set at each reversal, z2' = (S(w) - F) /
  |S(w)|, S(w) the Stribeck curve with the exact sign plus sigma w. Where the chapter divides
  by |S(0)| = 0 the level Fc is taken. z2 restarts from 0 at each reversal, as q_r does: carried
  across a reversal, the slow sliding's large z2 makes B |w| z2 push along the new motion and
  the rotor runs away (a 0.06 N m sine drove it to 25 rad/s within a millisecond). The tool's
  own reading differs (mjjoint.physics.twosep: a regularised sign in S, Omega from z1, z2 kept
  and the lag term applied only while it opposes the motion).
* Position dependence: the Coulomb level scaled by 1 + a cos(nu q + phi), nu any real number
  per motor radian (an eccentric bearing, a seal pressing unevenly).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StribeckLevels:
    """What the laws with a Stribeck curve share."""

    fc: float                 # Coulomb level [N m]
    fs: float                 # static level [N m]
    vs: float                 # Stribeck speed [rad/s]
    sigma2: float             # viscous [N m s/rad]


@dataclass(frozen=True)
class LuGre(StribeckLevels):
    z0: float = 0.01          # bristle deflection at the Coulomb level [rad]; sigma0 = fc / z0
    damping_ratio: float = 0.5  # sigma1 as a share of the bristle mode's critical damping

    def sigma0(self, fc: float) -> float:
        return fc / self.z0

    def rates(self, v: float, z: float, fc: float, inertia: float) -> tuple[float, float]:
        """(dz/dt, friction torque) at speed v, bristle z and Coulomb level fc."""
        s0 = self.sigma0(fc)
        g = fc + (self.fs - self.fc) * math.exp(-(v / self.vs) ** 2)
        dz = v - s0 * abs(v) * z / g
        s1 = 2.0 * self.damping_ratio * math.sqrt(s0 * inertia)
        return dz, s0 * z + s1 * dz + self.sigma2 * v


@dataclass(frozen=True)
class MaxwellSlip:
    stiffness: tuple[float, ...]   # k_i [N m/rad]
    slip: tuple[float, ...]        # F_i [N m]: element i slips at k_i |z_i| = F_i
    sigma2: float                  # viscous [N m s/rad]

    def rates(self, v: float, z: np.ndarray) -> np.ndarray:
        """dz_i/dt: an element sticks (follows v) until its spring reaches F_i, then slips."""
        k, f = np.asarray(self.stiffness), np.asarray(self.slip)
        holding = (np.abs(k * z) < f) | (np.sign(z) != np.sign(v))
        return np.where(holding, v, 0.0)

    def clip(self, z: np.ndarray) -> np.ndarray:
        limit = np.asarray(self.slip) / np.asarray(self.stiffness)
        return np.clip(z, -limit, limit)

    def spring(self, z: np.ndarray) -> float:
        """The elements' torque (viscous friction apart)."""
        return float(np.dot(self.stiffness, z))


@dataclass(frozen=True)
class TwoSEP(StribeckLevels):
    k: float                  # pre-sliding stiffness K [1/rad]
    b: float                  # attraction gain B [N m/rad] (z2 is in seconds)
    shape: float = 1.0        # Stribeck shape delta

    def steady(self, v: float) -> float:
        """S(w) = sgn(w) (Fc + (Fs - Fc) exp(-|w/Vs|^delta)) + sigma w (Eqs. 14-15)."""
        sg = 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)
        return sg * (self.fc + (self.fs - self.fc) * math.exp(-abs(v / self.vs) ** self.shape)) + self.sigma2 * v

    def force(self, v: float, z1: float, z2: float) -> float:
        return z1 + self.b * abs(v) * z2

    def rates(self, v: float, z1: float, z2: float, qr: float, omega: float) -> tuple[float, float, float]:
        """(z1', z2', q_r') with Omega the value the last reversal memorised."""
        s = self.steady(v)
        dz2 = (s - self.force(v, z1, z2)) / max(abs(s), self.fc)
        return abs(omega) * v * self.k * math.exp(-self.k * qr), dz2, abs(v)

    def reversal_memory(self, v: float, z1: float, z2: float) -> float:
        """Omega (Eq. 13) at a velocity reversal into the direction of v."""
        return math.copysign(self.fc, v) - self.force(v, z1, z2)

    def fast_rate(self, v: float, qr: float) -> float:
        """The lag state's relaxation rate B |w| / |S| [1/s], and the pre-sliding spring's K |w|
        while it is still far from saturation (K q_r < 10)."""
        spring = self.k if self.k * qr < 10.0 else 0.0
        return abs(v) * max(self.b / max(abs(self.steady(v)), self.fc), spring)


@dataclass(frozen=True)
class PositionDependence:
    """Coulomb level times 1 + amplitude cos(per_rad q + phase)."""

    amplitude: float
    per_rad: float      # cycles per motor radian times 2 pi: any real number
    phase: float = 0.0

    def factor(self, q: float) -> float:
        return 1.0 + self.amplitude * math.cos(self.per_rad * q + self.phase)
