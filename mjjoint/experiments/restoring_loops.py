"""Fig. 9: hysteretic restoring torque Gamma over a load-release cycle for mu = 1, 0.5, 0.1.

The spring is the object here, so the deflection is prescribed and the plugin's own kernels
are stepped along it: ``boucwen_step`` (Eq. 17, per deflection increment) and
``restoring_torque`` (Eq. 16). The path loads from rest to +a, then cycles -a -> +a; the
loop of that closed cycle is measured. Stiffness polynomial and Bouc-Wen shape are the
``Transmission``/``BoucWen`` defaults (k1 = 1e4, k3 = 1e8, hardening; x_u = 2 mrad), only mu
changes, and a = 3 x_u = 6 mrad takes x well into its plastic branch.

Since x does not depend on mu, the loop area is (1 - mu) times that of the purely plastic
spring: zero at mu = 1 (a single hardening curve, Fig. 9 (a)) and growing as mu falls.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numba import njit

from ..physics.boucwen import BoucWen, boucwen_step, restoring_torque
from ..physics.transmission import Transmission
from . import plotting
from .signals import loop_area

MUS = (1.0, 0.5, 0.1)
FIGURE = "fig9_restoring_loops.png"


@njit(cache=True)
def _drive(delta, mu, k1, k2, k3, a, beta, gamma, n):
    """Gamma and x along a prescribed deflection path, starting relaxed (x = 0)."""
    gam = np.empty(delta.shape[0])
    xs = np.empty(delta.shape[0])
    x = 0.0
    prev = 0.0
    for i in range(delta.shape[0]):
        x = boucwen_step(x, delta[i] - prev, a, beta, gamma, n)
        prev = delta[i]
        gam[i] = restoring_torque(delta[i], x, mu, k1, k2, k3)
        xs[i] = x
    return gam, xs


def restoring_response(delta: np.ndarray, transmission: Transmission) -> tuple[np.ndarray, np.ndarray]:
    """Gamma(delta, x) and x along ``delta`` [rad] for a transmission with hysteresis."""
    h = transmission.hysteresis if transmission.hysteresis is not None else BoucWen(mu=1.0)
    return _drive(np.asarray(delta, float), h.mu, transmission.k1, transmission.k2, transmission.k3,
                  h.a, h.beta, h.gamma, h.n)


def load_release_path(amplitude: float, points: int = 2000) -> tuple[np.ndarray, slice]:
    """0 -> +a (first loading), +a -> -a -> +a (the closed cycle); returns path and cycle slice."""
    up = np.linspace(0.0, amplitude, points)
    down = np.linspace(amplitude, -amplitude, 2 * points)[1:]
    back = np.linspace(-amplitude, amplitude, 2 * points)[1:-1]
    path = np.concatenate([up, down, back])
    return path, slice(points - 1, None)


def secant_stiffness(transmission: Transmission, amplitude: float) -> float:
    """Average slope of the hysteresis map over +-amplitude: the chord of the closed loop."""
    path, cyc = load_release_path(amplitude)
    gam, _ = restoring_response(path, transmission)
    return float((gam[cyc][0] - gam[cyc][len(path[cyc]) // 2]) / (2 * amplitude))


@dataclass
class Fig9Data:
    mus: tuple[float, ...]
    delta: np.ndarray        # the closed cycle's deflection [rad]
    gamma: np.ndarray        # (len(mus), n) restoring torque [N m]
    areas: np.ndarray        # loop areas: energy dissipated per cycle [J = N m rad]
    peak_torque: np.ndarray  # max |Gamma| on the cycle, the area's scale


def compute(mus: tuple[float, ...] = MUS, amplitude: float = 6e-3, points: int = 2000,
            transmission: Transmission = Transmission()) -> Fig9Data:
    path, cyc = load_release_path(amplitude, points)
    gammas = []
    for mu in mus:
        tr = replace(transmission, hysteresis=replace(transmission.hysteresis or BoucWen(), mu=mu))
        gammas.append(restoring_response(path, tr)[0][cyc])
    gammas = np.array(gammas)
    delta = path[cyc]
    areas = np.array([abs(loop_area(delta, g)) for g in gammas])
    return Fig9Data(tuple(mus), delta, gammas, areas, np.abs(gammas).max(axis=1))


def draw(data: Fig9Data, path: str | Path) -> Path:
    fig, axes = plotting.figure(1, len(data.mus), width=4.0 * len(data.mus), height=3.8, sharey=True)
    labels = "abcdefg"
    for i, (ax, mu, g, area) in enumerate(zip(np.atleast_1d(axes), data.mus, data.gamma, data.areas)):
        ax.plot(1e3 * data.delta, g, color=plotting.COLORS[i])
        ax.set(xlabel=r"$\delta$ [mrad]", title=f"({labels[i]}) $\\mu$ = {mu:g}, loop area {area:.3g} J")
    np.atleast_1d(axes)[0].set_ylabel(r"$\Gamma$ [N m]")
    return plotting.save(fig, path)


def write(out: str | Path) -> list[Path]:
    """Compute with the defaults and draw Fig. 9 into folder ``out``."""
    return [draw(compute(), Path(out) / FIGURE)]
