"""Figs. 12-13: least-squares identification from the down-chirp of the simulated joint.

Fig. 12, the actuator: with motor torque u and joint torque tau as inputs and motor velocity
w as output, J w' = u - tau/N - Fc sgn(w) - sigma w is linear in (J, Fc, sigma); w' is the
central difference of the sampled w. The identified model is then driven by the same u and
tau (implicit Euler, exact Coulomb stick) and its velocity drawn over the measured one.
Coulomb + viscous is the chapter's simplest static map, not the simulator's 2SEP: its
pre-sliding and Stribeck terms stay in the residual.

Fig. 13, the transmission: tau = Gamma(delta, x) + D delta' (Eqs. 16-18) with Bouc-Wen state x
(A = 1, n = 1) is linear in (mu k1, mu k3, (1 - mu) k1, (1 - mu) k3, D) once x is known, and x
follows from the measured torsion delta for given (beta, gamma). So (beta, gamma) are
searched (variable projection: scipy least_squares over ln beta and gamma/beta, from the three
best points of a coarse grid) with the five linear ones solved at every step; k1, k3 and mu are
read off the two pairs. Fits nearly as good lie along a narrow valley in which beta stays put
and gamma moves (gamma is the weaker of the two, and the classic loop's gamma = beta lies on
the bound): over ln beta and gamma/beta the valley runs along one axis, which the search
follows to its end; over x_u = 1/(beta + gamma) and gamma/beta it curves, and the search
stalled on its side.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from ..physics.boucwen import BoucWen
from ..physics.transmission import Transmission
from ..sim import Trace, held_controls
from . import plotting
from .restoring_loops import restoring_response


@dataclass(frozen=True)
class MotorFit:
    inertia: float   # J [kg m^2]
    coulomb: float   # Fc [N m]
    viscous: float   # sigma [N m s/rad]


@dataclass(frozen=True)
class TransmissionFit:
    k1: float        # [N m/rad]
    k3: float        # [N m/rad^3]
    mu: float        # elastic share (Eq. 16)
    damping: float   # D [N m s/rad]
    beta: float      # Bouc-Wen [1/rad]
    gamma: float


def fit_motor(tr: Trace) -> MotorFit:
    rate = 1.0 / (tr.t[1] - tr.t[0])
    accel = np.gradient(tr.qd, 1.0 / rate)
    regressors = np.column_stack([accel, np.sign(tr.qd), tr.qd])
    # The centred acceleration at a sample answers to the input held about it: the mean of the
    # sample's and the one before (``sim.held_controls``); the sample's own is half a sample late.
    drive = held_controls(tr.u, 1, tr.u[0]) - tr.tau / tr.gear_ratio
    (j, fc, sigma), *_ = np.linalg.lstsq(regressors, drive, rcond=None)
    return MotorFit(float(j), float(fc), float(sigma))


def replay_motor(fit: MotorFit, tr: Trace) -> np.ndarray:
    """Velocity of the identified actuator under the measured u and tau, from the measured w[0].

    Implicit Euler per sample: w1 = (J w0/h + f - Fc sgn w1)/(J/h + sigma), and w1 = 0 where
    |J w0/h + f| <= Fc (Coulomb sticks), so no regularisation of sgn is needed.
    """
    h = tr.t[1] - tr.t[0]
    drive = tr.u - tr.tau / tr.gear_ratio
    w = np.empty(len(drive))
    w[0] = tr.qd[0]
    m, den = fit.inertia / h, fit.inertia / h + fit.viscous
    for k in range(len(drive) - 1):
        p = m * w[k] + drive[k]
        w[k + 1] = 0.0 if abs(p) <= fit.coulomb else (p - np.copysign(fit.coulomb, p)) / den
    return w


def _hysteresis_state(delta: np.ndarray, beta: float, gamma: float) -> np.ndarray:
    shape = Transmission(k1=1.0, k2=0.0, k3=0.0, damping=0.0, hysteresis=BoucWen(mu=0.0, beta=beta, gamma=gamma))
    return restoring_response(delta, shape)[1]


def _transmission_regression(tr: Trace, shape: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Regressors, linear solution, beta and gamma for the Bouc-Wen shape (ln beta, gamma/beta)."""
    beta = float(np.exp(shape[0]))
    gamma = beta * float(shape[1])
    delta = tr.delta
    x = _hysteresis_state(delta, beta, gamma)
    rate = np.gradient(delta, tr.t[1] - tr.t[0])
    regressors = np.column_stack([delta, delta ** 3, x, x ** 3, rate])
    coef, *_ = np.linalg.lstsq(regressors, tr.tau, rcond=None)
    return regressors, coef, beta, gamma


# The shape's search box: beta from 5 to 1e5 1/rad (x_u = 1/(beta + gamma) from 0.1 rad down to
# 5 um), gamma/beta in [-0.9, 1] (gamma <= beta: ``BoucWen``).
SHAPE_BOUNDS = ([np.log(5.0), -0.9], [np.log(1e5), 1.0])


def fit_transmission(tr: Trace) -> tuple[TransmissionFit, np.ndarray]:
    """The fit and its torque prediction: least squares from each of the three best shapes on a
    9 x 5 grid over ``SHAPE_BOUNDS``, the best of the three kept."""
    def residual(shape):
        regressors, coef, *_ = _transmission_regression(tr, shape)
        return regressors @ coef - tr.tau

    lo, hi = SHAPE_BOUNDS
    grid = [(lb, r) for lb in np.linspace(lo[0], hi[0], 9) for r in np.linspace(lo[1], hi[1], 5)]
    starts = sorted(grid, key=lambda g: float(np.sum(residual(g) ** 2)))[:3]
    sol = min((least_squares(residual, g, bounds=SHAPE_BOUNDS, diff_step=1e-4) for g in starts), key=lambda r: r.cost)
    regressors, (e1, e3, p1, p3, damping), beta, gamma = _transmission_regression(tr, sol.x)
    k1 = e1 + p1
    fit = TransmissionFit(float(k1), float(e3 + p3), float(e1 / k1), float(damping), beta, gamma)
    return fit, regressors @ np.array([e1, e3, p1, p3, damping])


@dataclass
class IdentData:
    trace: Trace
    motor: MotorFit
    velocity: np.ndarray       # replayed identified velocity [rad/s]
    transmission: TransmissionFit
    torque: np.ndarray         # identified tau [N m]


def identify(tr: Trace) -> IdentData:
    motor = fit_motor(tr)
    transmission, torque = fit_transmission(tr)
    return IdentData(tr, motor, replay_motor(motor, tr), transmission, torque)


def nrmse(measured: np.ndarray, model: np.ndarray) -> float:
    return float(np.sqrt(np.mean((model - measured) ** 2)) / np.std(measured))


def draw(data: IdentData, path: str | Path) -> Path:
    tr, m, t = data.trace, data.motor, data.transmission
    fig = plotting.plt.figure(figsize=(11, 8), constrained_layout=True)
    grid = fig.add_gridspec(2, 2, width_ratios=(2, 1))
    ax_w, ax_tau = fig.add_subplot(grid[0, 0]), fig.add_subplot(grid[1, 0])
    ax_h = fig.add_subplot(grid[:, 1])
    ax_w.plot(tr.t, tr.qd, color="0.5", label="measured (simulated joint)")
    ax_w.plot(tr.t, data.velocity, color=plotting.COLORS[0], lw=0.8,
              label=f"identified: J = {m.inertia:.3g} kg m², Fc = {m.coulomb:.3g} N m, "
                    f"σ = {m.viscous:.2g} N m s/rad (NRMSE {nrmse(tr.qd, data.velocity):.2f})")
    ax_w.set(ylabel=r"$\dot q$ [rad/s]", title="(Fig. 12) velocity response to the down-chirp")
    ax_tau.plot(tr.t, tr.tau, color="0.5", label="measured")
    ax_tau.plot(tr.t, data.torque, color=plotting.COLORS[1], lw=0.8,
                label=f"identified: k1 = {t.k1:.4g}, k3 = {t.k3:.3g}, μ = {t.mu:.2f}, D = {t.damping:.2f} "
                      f"(NRMSE {nrmse(tr.tau, data.torque):.3f})")
    ax_tau.set(xlabel="t [s]", ylabel=r"$\tau$ [N m]", title="(Fig. 13 a) joint torque")
    ax_h.plot(1e3 * tr.delta, tr.tau, color="0.5", lw=1.5, label="measured")
    ax_h.plot(1e3 * tr.delta, data.torque, color=plotting.COLORS[1], lw=0.5, label="identified")
    ax_h.set(xlabel=r"$\delta$ [mrad]", ylabel=r"$\tau$ [N m]", title="(Fig. 13 b) torsion-torque hysteresis")
    for ax in (ax_w, ax_tau, ax_h):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper left", fontsize=8)
    return plotting.save(fig, path)
