"""Fig. 8: static Stribeck map against the 2SEP dynamic friction in velocity-force coordinates.

Friction is the object here, so the motor velocity is prescribed and the plugin's own kernels
are stepped along it (``twosep_step`` advances the states over a step at velocity w,
``twosep_force`` gives F = z1 + B|w|z2), as the plugin's advance and compute do; with the
velocity prescribed there is no inertia, so the lag force is the literal one (the plugin takes
it implicitly against the motor's inertia, ``coupling.kernels.joint_evaluate``).

(a) the static map S(w) of Eqs. (14)-(15), discontinuous at w = 0;
(b) the response to a cyclic velocity of increasing frequency: at each reversal the force
    passes through the pre-sliding transition (z1, Eq. 12) and then lags behind S(w) (z2,
    Eq. 14); the faster the reversal, the wider the loop (frictional lag).

Checks used by the tests: at constant velocity F converges to S(w); after a reversal the
pre-sliding state z1 saturates at +-Fc; the lag loop area grows with frequency. Parameters are
the ``TwoSEP`` defaults (Fc 0.08, Fs 0.12 N m, Vs 0.5 rad/s, K 1000 1/rad, B 50 N m/rad).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from ..physics.stribeck import steady_state
from ..physics.twosep import TwoSEP, twosep_force, twosep_step
from . import plotting
from .signals import loop_area

FREQUENCIES = (0.5, 2.0, 8.0, 32.0)   # [Hz] of the cyclic velocity, Fig. 8 (b)
FIGURE = "fig8_friction_lag.png"


@njit(cache=True)
def _drive(w, h, fc, fs, vs, shape, sigma, k, b, asym, sigma_asym):
    """F and z1 along a prescribed velocity sequence, w[i] held over a step of length h[i]."""
    n = w.shape[0]
    force = np.empty(n)
    z1s = np.empty(n)
    z1 = z2 = omega = qr = wsign = 0.0
    for i in range(n):
        z1, z2, omega, qr, wsign = twosep_step(z1, z2, omega, qr, wsign, w[i], h[i], fc, fs, vs, shape,
                                               sigma, k, b, asym, sigma_asym)
        force[i] = twosep_force(z1, z2, w[i], b)
        z1s[i] = z1
    return force, z1s


def twosep_response(w: np.ndarray, h, p: TwoSEP = TwoSEP()) -> tuple[np.ndarray, np.ndarray]:
    """2SEP force F and pre-sliding state z1 from rest, for velocities ``w`` [rad/s] held over
    steps ``h`` [s] (a scalar or one per sample)."""
    w = np.asarray(w, float)
    h = np.ascontiguousarray(np.broadcast_to(np.asarray(h, float), w.shape))
    return _drive(w, h, p.fc, p.fs, p.vs, p.shape, p.sigma, p.k, p.b, p.asym, p.sigma_asym)


def static_map(w: np.ndarray, p: TwoSEP = TwoSEP()) -> np.ndarray:
    """S(w) of Eqs. (14)-(15) (0 at w = 0, the sign's value)."""
    return np.array([steady_state(float(v), p.fc, p.fs, p.vs, p.shape, p.sigma, p.asym, p.sigma_asym) for v in w])


def stepped_cycles(amplitude: float, frequencies, periods: int, steps_per_period: int = 20000):
    """w = amplitude sin(2 pi f t), ``periods`` whole cycles per frequency, frequencies in turn.

    Whole cycles keep w continuous across the frequency changes. Returns w, the step length
    of each sample and, per frequency, the slice of its last cycle.
    """
    phase = 2 * np.pi * np.arange(periods * steps_per_period) / steps_per_period
    w = np.tile(amplitude * np.sin(phase), len(frequencies))
    h = np.repeat([1.0 / (f * steps_per_period) for f in frequencies], periods * steps_per_period)
    block = periods * steps_per_period
    last = [slice((i + 1) * block - steps_per_period, (i + 1) * block) for i in range(len(frequencies))]
    return w, h, last


def presliding_cycle(p: TwoSEP, amplitude: float, frequency: float = 0.5, periods: int = 2,
                     steps_per_period: int = 20000):
    """Displacement q = amplitude sin(2 pi f t) (smooth reversals); returns q, F, z1 from rest."""
    h = 1.0 / (frequency * steps_per_period)
    t = np.arange(periods * steps_per_period) * h
    w = amplitude * 2 * np.pi * frequency * np.cos(2 * np.pi * frequency * t)
    force, z1 = twosep_response(w, h, p)
    return np.cumsum(w) * h, force, z1


@dataclass
class Fig8Data:
    params: TwoSEP
    w_map: np.ndarray          # (a) velocity grid [rad/s]
    s_map: np.ndarray          # (a) S(w) [N m]
    frequencies: tuple[float, ...]
    t: np.ndarray              # (b) time of the stepped-frequency run [s]
    w: np.ndarray              # (b) prescribed velocity [rad/s]
    force: np.ndarray          # (b) 2SEP friction [N m]
    cycles: list               # (b) slice of the last cycle of each frequency
    areas: np.ndarray          # lag-loop area of those cycles [N m rad/s]
    q_pre: np.ndarray          # (c) pre-sliding displacement [rad]
    z1_pre: np.ndarray         # (c) pre-sliding state z1 [N m]


def compute(p: TwoSEP = TwoSEP(), amplitude: float = 2.0, frequencies: tuple[float, ...] = FREQUENCIES,
            periods: int = 3, steps_per_period: int = 20000) -> Fig8Data:
    """(b) ``periods`` cycles at each frequency, increasing; (c) +-10/K pre-sliding cycles."""
    if list(frequencies) != sorted(frequencies):
        raise ValueError(f"frequencies={frequencies!r} must increase")
    w_map = np.linspace(-amplitude, amplitude, 2001)
    w, h, cycles = stepped_cycles(amplitude, frequencies, periods, steps_per_period)
    force, _ = twosep_response(w, h, p)
    areas = np.array([abs(loop_area(w[c], force[c])) for c in cycles])
    q_pre, _, z1_pre = presliding_cycle(p, 10.0 / p.k)
    return Fig8Data(p, w_map, static_map(w_map, p), tuple(frequencies), np.cumsum(h) - h[0], w, force,
                    cycles, areas, q_pre, z1_pre)


def draw(data: Fig8Data, path: str | Path) -> Path:
    fig, (ax_a, ax_b, ax_c) = plotting.figure(1, 3, width=15.0, height=4.2)
    branches = (data.w_map > 0, data.w_map < 0)
    for sel in branches:
        ax_a.plot(data.w_map[sel], data.s_map[sel], color="k")
        ax_b.plot(data.w_map[sel], data.s_map[sel], "k:", lw=1)
    ax_a.plot([0, 0], [-data.params.fs, data.params.fs], "k:", lw=1)
    ax_a.set(xlabel="w [rad/s]", ylabel="F [N m]", title="(a) static Stribeck map S(w)")
    for i, (f, c, area) in enumerate(zip(data.frequencies, data.cycles, data.areas)):
        ax_b.plot(data.w[c], data.force[c], color=plotting.COLORS[i], label=f"{f:g} Hz, area {area:.3g}")
    ax_b.set(xlabel="w [rad/s]", ylabel="F [N m]",
             title="(b) 2SEP, cyclic w of increasing frequency f")
    ax_b.legend(loc="upper left", fontsize="small")
    ax_c.plot(1e3 * data.q_pre, data.z1_pre, color="k")
    for lvl in (-data.params.fc, data.params.fc):
        ax_c.axhline(lvl, color="tab:red", ls=":", lw=1)
    ax_c.set(xlabel="q [mrad]", ylabel="$z_1$ [N m]", title=r"(c) pre-sliding state $z_1$ saturating at $\pm F_c$")
    return plotting.save(fig, path)


def write(out: str | Path) -> list[Path]:
    """Compute with the defaults and draw Fig. 8 into folder ``out``."""
    return [draw(compute(), Path(out) / FIGURE)]
