"""Fig. 2: rigid joint, Eq. (2), against elastic joints, Eq. (3), with K = 1e3 and K = 1e8.

    rigid   (m + M) q'' + (d + D) q' = u                          (2), theta = q
    elastic m q'' + d q' + K (q - theta) = u,
            M theta'' + D theta' - K (q - theta) = 0              (3)

The chapter leaves m, M, d, D open; here m = M = 1 kg m^2 and d = D = 10 N m s/rad. The
damping is chosen high so that the rigid velocity settles (time constant (m+M)/(d+D) = 0.1 s)
within a few periods of the K = 1e3 mode, sqrt(K (1/m + 1/M)) = 44.7 rad/s (7.1 Hz, 11 %
damping): only then is the spring's deflection, u/(2K) = 0.5 mrad per N m, a visible part of
theta. With d = D = 1 the same oscillation drowns in the 1 s ramp (0.02 % of theta).

Both joints are MuJoCo models. The rigid one is a single hinge of inertia m + M with native
damping d + D. The elastic ones use the ``mjjoint.joint`` plugin with the chapter's terms
reduced to Eq. (3): motor friction ``StaticFriction.viscous(d)``, load friction
``LoadFriction(fc=0, viscous=D)``, a linear spring (k2 = k3 = 0, no hysteresis, no
transmission damping, gear ratio 1). The plugin's forces are explicit, so K = 1e8
(14 142 rad/s) needs a 10 us step (w h = 0.14); 100 us suffices for the rest.

Simulated frequency responses come from the impulse response: H = W / (j w U) with W the FFT
of the link velocity, which decays, unlike theta, which keeps the integrator's offset. The
analytic |H(jw)| and step responses of Eqs. (2)-(3) (scipy) are the reference.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import signal

from ..joint import JointParams
from ..params import check
from ..physics.load import LoadFriction
from ..physics.stribeck import StaticFriction
from ..physics.transmission import Transmission
from ..sim import Simulator
from . import plotting
from .models import compile_mjcf, inertia_body, mjcf, rollout
from .signals import impulse_frf

STIFFNESSES = (1e3, 1e8)   # K of H2 and H3 [N m/rad]
FIGURE = "fig2_rigid_vs_elastic.png"


@dataclass(frozen=True)
class LinearJoint:
    """Masses [kg m^2] and dampings [N m s/rad] of Eqs. (2)-(3).

    ``c`` damps the spring itself (the transmission damping D of Eq. 18; Eq. 3 has none), so
    that the linearised gear of Sec. 4, reflected to the link side, is this model too.
    """

    m: float = 1.0
    M: float = 1.0
    d: float = 10.0
    D: float = 10.0
    c: float = 0.0

    def __post_init__(self) -> None:
        for name in ("m", "M", "d", "D"):
            check(name, getattr(self, name), 0.0, lo_open=True)
        check("c", self.c, 0.0)

    def _denominator(self, K: float) -> np.ndarray:
        spring = [self.c, K]
        motor = np.polyadd([self.m, self.d, 0.0], spring)
        link = np.polyadd([self.M, self.D, 0.0], spring)
        return np.polysub(np.polymul(motor, link), np.polymul(spring, spring))

    def transfer(self, K: float | None) -> signal.TransferFunction:
        """theta(s)/U(s): Eq. (2) for K None, else Eq. (3)."""
        if K is None:
            return signal.TransferFunction([1.0], [self.m + self.M, self.d + self.D, 0.0])
        return signal.TransferFunction([self.c, K], self._denominator(K))

    def motor_transfer(self, K: float, locked: bool = False) -> signal.TransferFunction:
        """q(s)/U(s) of Eq. (3); ``locked``: theta held at 0 (the rotor on the spring alone)."""
        if locked:
            return signal.TransferFunction([1.0], [self.m, self.d + self.c, K])
        return signal.TransferFunction([self.M, self.D + self.c, K], self._denominator(K))


def timestep_for(K: float | None, joint: LinearJoint) -> float:
    """1e-5 s where the spring mode is fast, 1e-4 s otherwise (w h <= 0.15 either way)."""
    if K is None:
        return 1e-4
    w = np.sqrt(K * (1.0 / joint.m + 1.0 / joint.M))
    return 1e-4 if w * 1e-4 <= 0.15 else 1e-5


def rigid_model(joint: LinearJoint, timestep: float):
    body = inertia_body("joint", "q", joint.m + joint.M, damping=joint.d + joint.D)
    return compile_mjcf(mjcf("rigid joint, Eq. 2", timestep, body, "q"))


def elastic_model(joint: LinearJoint, K: float, timestep: float):
    params = JointParams(
        motor_joint="motor", link_joint="link", friction=StaticFriction.viscous(joint.d),
        transmission=Transmission(gear_ratio=1.0, k1=K, k2=0.0, k3=0.0, damping=0.0, hysteresis=None),
        load_friction=LoadFriction(fc=0.0, viscous=joint.D))
    bodies = inertia_body("rotor", "motor", joint.m) + inertia_body("load", "link", joint.M)
    return compile_mjcf(mjcf(f"elastic joint, Eq. 3, K={K:g}", timestep, bodies, "motor", params))


def link_response(joint: LinearJoint, K: float | None, u: np.ndarray, sample_rate: float,
                  timestep: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """theta and theta' of the rigid (K None) or elastic joint under motor torques ``u``."""
    dt = timestep if timestep is not None else timestep_for(K, joint)
    if K is None:
        s = rollout(rigid_model(joint, dt), u, sample_rate)
        return s.qpos[:, 0], s.qvel[:, 0]
    tr = Simulator(elastic_model(joint, K, dt), sample_rate=sample_rate).run(u)
    return tr.theta, tr.thetad


@dataclass
class Fig2Data:
    joint: LinearJoint
    stiffnesses: tuple[float, ...]
    t: np.ndarray                 # step response time [s]
    step_rigid: np.ndarray        # theta of Eq. (2) for u = 1 N m
    step_elastic: np.ndarray      # (len(stiffnesses), n) theta of Eq. (3)
    step_analytic: np.ndarray     # (1 + len(stiffnesses), n): H1, H2, H3 by scipy
    f: np.ndarray                 # FRF frequencies [Hz]
    frf_rigid: np.ndarray         # simulated theta/U
    frf_elastic: np.ndarray       # (len(stiffnesses), nf) simulated theta/U
    frf_analytic: np.ndarray      # (1 + len(stiffnesses), nf) |H1|, |H2|, |H3|


def simulate_frf(joint: LinearJoint, K: float | None, duration: float, sample_rate: float,
                 timestep: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """theta/U from the link-velocity response to a one-sample torque pulse at t = 0."""
    n = round(duration * sample_rate)
    u = np.zeros(n)
    u[0] = sample_rate  # unit area: a discrete Dirac
    _, w = link_response(joint, K, u, sample_rate, timestep)
    f, h = impulse_frf(u, w, sample_rate)
    jw = 2j * np.pi * f
    jw[0] = 1.0
    out = h / jw
    out[0] = np.nan  # theta/U has a pole at s = 0
    return f, out


def compute(joint: LinearJoint = LinearJoint(), stiffnesses: tuple[float, ...] = STIFFNESSES,
            step_duration: float = 0.5, frf_duration: float = 4.0, frf_rate: float = 10000.0) -> Fig2Data:
    """Step responses at 1 kHz and impulse FRFs at ``frf_rate`` (Nyquist above K = 1e8's 2.25 kHz)."""
    rate = 1000.0
    n = round(step_duration * rate)
    u = np.ones(n)
    t = np.arange(n) / rate
    rigid, _ = link_response(joint, None, u, rate, timestep=1e-5)
    elastic = np.array([link_response(joint, K, u, rate, timestep=1e-5)[0] for K in stiffnesses])
    # The simulator holds u[0] over the first period, so the simulated step starts at t = 0.
    analytic = np.array([signal.step(joint.transfer(K), T=t)[1] for K in (None, *stiffnesses)])
    f, frf_rigid = simulate_frf(joint, None, frf_duration, frf_rate, timestep=1e-4)
    frf_el = np.array([simulate_frf(joint, K, frf_duration, frf_rate, timestep=timestep_for(K, joint))[1]
                       for K in stiffnesses])
    w = 2 * np.pi * f[1:]
    ana = np.array([np.r_[np.nan, np.abs(signal.freqresp(joint.transfer(K), w)[1])] for K in (None, *stiffnesses)])
    return Fig2Data(joint, tuple(stiffnesses), t, rigid, elastic, analytic, f, frf_rigid, frf_el, ana)


def draw(data: Fig2Data, path: str | Path) -> Path:
    fig, (ax_t, ax_d, ax_f) = plotting.figure(3, 1, height=10.0)
    ax_t.plot(data.t, data.step_rigid, lw=2.5, color="0.6", label="H1 rigid (MuJoCo hinge)")
    for K, y, c in zip(data.stiffnesses, data.step_elastic, plotting.COLORS):
        ax_t.plot(data.t, y, color=c, label=f"K = {K:.0e} (plugin)")
        ax_d.plot(data.t, 1e3 * (y - data.step_rigid), color=c, label=f"K = {K:.0e}")
    for y in data.step_analytic:
        ax_t.plot(data.t, y, "k:", lw=1)
    ax_t.plot([], [], "k:", lw=1, label="analytic Eqs. 2-3")
    ax_t.set(xlabel="t [s]", ylabel=r"$\theta$ [rad]", title="(a) step response, u = 1 N m")
    ax_t.legend(loc="upper left")
    ax_d.set(xlabel="t [s]", ylabel=r"$\theta - \theta_{rigid}$ [mrad]", title="(a) deviation from the rigid joint")
    ax_d.legend(loc="lower right")
    sel = data.f > 0
    ax_f.loglog(data.f[sel], np.abs(data.frf_rigid[sel]), lw=2.5, color="0.6", label="H1 rigid")
    for K, h, c in zip(data.stiffnesses, data.frf_elastic, plotting.COLORS):
        ax_f.loglog(data.f[sel], np.abs(h[sel]), color=c, label=f"K = {K:.0e}")
    for a in data.frf_analytic:
        ax_f.loglog(data.f[sel], a[sel], "k:", lw=1)
    ax_f.plot([], [], "k:", lw=1, label="analytic")
    ax_f.set(xlabel="f [Hz]", ylabel=r"$|\theta/U|$ [rad/(N m)]",
             title="(b) amplitude response (FFT of the simulated impulse response)")
    ax_f.legend(loc="lower left")
    return plotting.save(fig, path)


def write(out: str | Path) -> list[Path]:
    """Compute with the defaults and draw Fig. 2 into folder ``out``."""
    return [draw(compute(), Path(out) / FIGURE)]
