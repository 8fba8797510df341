"""Sec. 4: the chapter's laboratory experiments, run on the simulated arm (Simulator defaults).

All runs use the shipped arm and joint physics (``ArmSpec()``, ``JointParams()``: 160:1
harmonic drive with 2SEP motor friction, hardening Bouc-Wen spring, bearing friction, 4-segment
flexible rod with 1 kg tip, gravity), driven open loop by the motor torque u = k_m i.

* Impulse FRFs (Fig. 11): 5 A for 1.5 ms (u = 5 k_m = 1.25 N m), sampled at 2 kHz so the pulse
  is three whole samples; W(jw)/U(jw) from motor velocity and input by FFT. Free link;
  output locked (``link_joint="world"``) and relaxed; output locked and prestressed: the motor
  is turned (torque ramp to ``prestress``, hold, ramp back to 0) until the transmission is
  twisted, released so that friction holds what it can, then kicked in the same direction.
  A joint without friction cannot hold the twist: ``hold_prestress`` keeps the torque on
  instead, and the pulse rides on it. Bins where the pulse has under a tenth of its peak
  spectrum (614-725 Hz around its 667 Hz zero) are masked (``signals.INPUT_FLOOR``).
  The fourth FRF, W/T after a shock on the load side, is ``load_shock``'s.
* Down-chirp 30 -> 1 Hz (Figs. 12-13): motor velocity, transmission torque tau, and the
  torsion-torque (delta, tau) hysteresis loops; actuator and transmission identified from
  them by least squares (``identification``).
* Gravity (Fig. 14 (a)): a low constant torque, 0.125 N m (0.5 A), 15 % above the
  m l g / N + Fc = 0.109 N m needed to pass the horizontal, drives the link slowly round
  (one turn in ~10 s; lower drives only creep over the horizontal); tau against theta over
  whole revolutions is fitted by m l g sin(theta) + c (c: the bearing's Coulomb friction in
  the one direction of motion), and m l compared with the model's, computed from the MjModel
  bodies (subtree mass of the hub times its centre-of-mass lever).
* Step (Fig. 14 (b)): 0.105 N m (0.42 A) from t = 0.5 s, chosen so that the link velocity
  peaks at a few tens of deg/s (~29; the chapter reports ~60) and gravity then brakes it to a
  standstill below the horizontal (~57 deg): N (u - Fc) = 4.0 N m stays below m l g = 4.6 N m,
  so the motor's sliding friction alone holds the link. At 0.11 N m (4.8 N m) only the
  bearing's Coulomb friction (0.5 N m) can hold it past the horizontal.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ..assets.builder import ArmSpec
from ..excitation import Chirp, Impulse, Step
from ..joint import GROUND, JointParams
from ..sim import Simulator, Trace
from . import identification, plotting
from .load_shock import ShockData, shock_frf
from .signals import impulse_frf, sampled_mass_line

IMPULSE_CURRENT = 5.0     # [A], Sec. 4
IMPULSE_WIDTH = 1.5e-3    # [s], Sec. 4
FRF_RATE = 2000.0         # [Hz]: 1.5 ms = 3 samples; the arm's 0.5 ms step = 1 substep
CONDITIONS = ("free", "locked, relaxed", "locked, prestressed")


def link_lever_mass(model: mujoco.MjModel, link_body: str = "hub", link_joint: str = "link") -> float:
    """m l of Eq. (9): mass of everything the link hinge carries times its COG lever [kg m]."""
    data = mujoco.MjData(model)
    mujoco.mj_resetData(model, data)
    mujoco.mj_forward(model, data)
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, link_body)
    jnt = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, link_joint)
    axis = data.xaxis[jnt]
    r = data.subtree_com[body] - data.xanchor[jnt]
    lever = np.linalg.norm(r - axis * (r @ axis))  # distance from the hinge axis
    return float(model.body_subtreemass[body] * lever)


# ---- impulse FRFs (Fig. 11) ---------------------------------------------------------------

@dataclass
class FrfData:
    f: np.ndarray
    frf: dict                 # condition -> W/U (complex)
    t: np.ndarray             # record time, impulse at t_impulse [s]
    qd: dict                  # condition -> motor velocity record [rad/s]
    u: np.ndarray             # impulse record [N m]
    motor_inertia: float      # [kg m^2], for the mass line 1/(w m)
    prestress_delta: float    # deflection left by the prestress program [rad]
    shock: ShockData          # W/T of the free arm struck on the load side


def impulse(arm: ArmSpec, t0: float, duration: float, current: float = IMPULSE_CURRENT) -> np.ndarray:
    """The chapter's 5 A (or ``current``), 1.5 ms pulse through k_m, sampled at FRF_RATE."""
    return Impulse(amplitude=current * arm.k_m, t0=t0, width=IMPULSE_WIDTH).sample(FRF_RATE, duration)


def prestress_program(level: float, rate: float = FRF_RATE, hold: bool = False) -> np.ndarray:
    """Turn the motor against the locked output (1 s ramp, 0.5 s hold), release (1 s), wait 0.5 s.

    ``hold``: keep ``level`` on instead of releasing (1 s ramp, 2 s hold).
    """
    r = int(rate)
    release = np.full(3 * r // 2, level) if hold else np.concatenate([np.linspace(level, 0.0, r), np.zeros(r // 2)])
    return np.concatenate([np.linspace(0.0, level, r), np.full(r // 2, level), release])


def impulse_frfs(arm: ArmSpec = ArmSpec(), joint: JointParams = JointParams(), duration: float = 2.0,
                 prestress: float = 0.2, t_impulse: float = 0.05, current: float = IMPULSE_CURRENT,
                 hold_prestress: bool = False) -> FrfData:
    u = impulse(arm, t_impulse, duration, current)
    n = len(u)
    locked = joint.replace(link_joint=GROUND)
    free_sim = Simulator(sample_rate=FRF_RATE, arm=arm, joint=joint)
    locked_sim = Simulator(sample_rate=FRF_RATE, arm=arm, joint=locked)
    records = {CONDITIONS[0]: free_sim.run(u).qd, CONDITIONS[1]: locked_sim.run(u).qd}
    pre = prestress_program(prestress, hold=hold_prestress)
    tr = locked_sim.run(np.concatenate([pre, u + pre[-1]]))
    records[CONDITIONS[2]] = tr.qd[len(pre):]
    frf = {}
    for name, qd in records.items():
        f, frf[name] = impulse_frf(u, qd, FRF_RATE)
    shock = shock_frf(arm, joint, FRF_RATE, duration, t_impulse, IMPULSE_WIDTH)
    return FrfData(f, frf, np.arange(n) / FRF_RATE, records, u, arm.motor_inertia, float(tr.delta[len(pre)]),
                   shock)


def draw_frfs(data: FrfData, path: str | Path) -> Path:
    fig, (ax_f, ax_t) = plotting.figure(2, 1, height=8.0)
    sel = data.f > 0
    for i, (name, h) in enumerate(data.frf.items()):
        ax_f.loglog(data.f[sel], np.abs(h[sel]), color=plotting.COLORS[i], label=f"W/U {name}")
        ax_t.plot(1e3 * data.t, data.qd[name], color=plotting.COLORS[i], label=name)
    shock = data.shock
    ax_f.loglog(shock.f[sel], shock.trace.gear_ratio * np.abs(shock.frf[sel]), color=plotting.COLORS[3],
                label="N W/T free, shock on the load")
    ax_f.loglog(data.f[sel], sampled_mass_line(data.f[sel], data.motor_inertia, FRF_RATE), "k:", lw=1,
                label="rotor mass line (sampled)")
    ax_f.set(xlabel="f [Hz]", ylabel="|W/U|, N |W/T| [rad/s/(N m)]",
             title=f"(Fig. 11) FRFs from a {IMPULSE_CURRENT:g} A, {1e3 * IMPULSE_WIDTH:g} ms impulse")
    ax_f.legend(loc="lower left")
    ax_t.plot(1e3 * data.t, shock.trace.qd, color=plotting.COLORS[3], label="free, shock on the load")
    ax_t.set(xlabel="t [ms]", ylabel=r"$\dot q$ [rad/s]", title="impulse responses", xlim=(0, 400))
    ax_t.legend(loc="upper right")
    return plotting.save(fig, path)


# ---- down-chirp (Figs. 12-13) ------------------------------------------------------------

@dataclass
class ChirpData:
    trace: Trace
    f_start: float
    f_end: float


def chirp_run(arm: ArmSpec = ArmSpec(), joint: JointParams = JointParams(), amplitude: float = 0.2,
              duration: float = 20.0) -> ChirpData:
    """0.2 N m (0.8 A): slides the motor through its friction at every cycle, link swings ~10 deg."""
    chirp = Chirp(amplitude=amplitude, f_start=30.0, f_end=1.0, sweep="linear")
    sim = Simulator(arm=arm, joint=joint)
    return ChirpData(sim.run(chirp.sample(sim.sample_rate, duration)), chirp.f_start, chirp.f_end)


def draw_chirp(data: ChirpData, path: str | Path) -> Path:
    tr = data.trace
    fig = plotting.plt.figure(figsize=(11, 8), constrained_layout=True)
    grid = fig.add_gridspec(3, 2, width_ratios=(2, 1))
    ax_w, ax_tau, ax_u = (fig.add_subplot(grid[i, 0]) for i in range(3))
    ax_h = fig.add_subplot(grid[:, 1])
    ax_u.plot(tr.t, tr.u, color="0.4")
    ax_u.set(xlabel="t [s]", ylabel="u [N m]", title=f"input: down-chirp {data.f_start:g} -> {data.f_end:g} Hz")
    ax_w.plot(tr.t, tr.qd, color=plotting.COLORS[0])
    ax_w.set(ylabel=r"$\dot q$ [rad/s]", title="(Fig. 12) motor velocity")
    ax_tau.plot(tr.t, tr.tau, color=plotting.COLORS[1])
    ax_tau.set(ylabel=r"$\tau$ [N m]", title="(Fig. 13 a) transmission torque")
    ax_h.plot(1e3 * tr.delta, tr.tau, color=plotting.COLORS[1], lw=0.6)
    ax_h.set(xlabel=r"$\delta = q/N - \theta$ [mrad]", ylabel=r"$\tau$ [N m]", title="(Fig. 13 b) torsion-torque hysteresis")
    for ax in (ax_w, ax_tau, ax_u, ax_h):
        ax.grid(True, alpha=0.3)
    return plotting.save(fig, path)


# ---- gravity (Fig. 14 a) ----------------------------------------------------------------

@dataclass
class GravityData:
    theta: np.ndarray          # link angle over the fitted whole revolutions [rad]
    tau: np.ndarray            # transmission torque there [N m]
    lever_mass: float          # fitted m l [kg m]
    offset: float              # fitted constant (bearing Coulomb friction) [N m]
    lever_mass_model: float    # m l of the MjModel [kg m]
    drive: float               # constant motor torque [N m]
    gravity: float             # [m/s^2]

    @property
    def relative_error(self) -> float:
        return self.lever_mass / self.lever_mass_model - 1.0


def gravity_sweep(arm: ArmSpec = ArmSpec(), joint: JointParams = JointParams(), drive: float = 0.125,
                  duration: float = 30.0) -> GravityData:
    sim = Simulator(arm=arm, joint=joint)
    tr = sim.run(np.full(round(duration * sim.sample_rate), drive))
    turns = np.floor(tr.theta / (2 * np.pi))
    if turns[-1] < 2:
        raise ValueError(f"drive={drive:g} N m turned the link over {int(turns[-1])} times in {duration:g} s; "
                         "need 2 (raise drive or duration)")
    # Whole revolutions only, after the first (the start-up transient): sin averages fairly.
    sel = (turns >= 1) & (turns < turns[-1])
    g = float(np.linalg.norm(sim.model.opt.gravity))
    a = np.column_stack([g * np.sin(tr.theta[sel]), np.ones(sel.sum())])
    (ml, c), *_ = np.linalg.lstsq(a, tr.tau[sel], rcond=None)
    return GravityData(tr.theta[sel], tr.tau[sel], float(ml), float(c), link_lever_mass(sim.model), drive, g)


def draw_gravity(data: GravityData, path: str | Path) -> Path:
    fig, ax = plotting.figure(1, 1, height=4.5)
    th = np.mod(data.theta, 2 * np.pi)
    ax.plot(np.degrees(th), data.tau, ".", ms=1.5, color=plotting.COLORS[0], label=r"simulated $\tau$")
    grid = np.linspace(0, 2 * np.pi, 361)
    ax.plot(np.degrees(grid), data.lever_mass * data.gravity * np.sin(grid) + data.offset, "k", lw=1.5,
            label=f"fit: m l = {data.lever_mass:.4f} kg m, c = {data.offset:.3f} N m")
    ax.plot([], [], " ", label=f"model m l = {data.lever_mass_model:.4f} kg m "
                               f"({100 * data.relative_error:+.1f} %)")
    ax.set(xlabel=r"$\theta$ [deg]", ylabel=r"$\tau$ [N m]",
           title=f"(Fig. 14 a) gravity, constant drive {data.drive:g} N m")
    ax.legend(loc="lower left")
    return plotting.save(fig, path)


# ---- step (Fig. 14 b) -------------------------------------------------------------------

@dataclass
class StepData:
    trace: Trace
    step: float
    t_step: float

    @property
    def peak_velocity_deg(self) -> float:
        return float(np.degrees(self.trace.thetad.max()))


def step_run(arm: ArmSpec = ArmSpec(), joint: JointParams = JointParams(), step: float = 0.105,
             t_step: float = 0.5, duration: float = 10.0) -> StepData:
    sim = Simulator(arm=arm, joint=joint)
    return StepData(sim.run(Step(amplitude=step, t0=t_step).sample(sim.sample_rate, duration)), step, t_step)


def draw_step(data: StepData, path: str | Path) -> Path:
    tr = data.trace
    fig, (ax_v, ax_t) = plotting.figure(2, 1, height=6.5, sharex=True)
    ax_v.plot(tr.t, np.degrees(tr.thetad), color=plotting.COLORS[0])
    ax_v.set(ylabel=r"$\dot\theta$ [deg/s]",
             title=f"(Fig. 14 b) link velocity, step {data.step:g} N m at {data.t_step:g} s "
                   f"(peak {data.peak_velocity_deg:.0f} deg/s)")
    ax_t.plot(tr.t, tr.u * tr.gear_ratio, color="0.5", label="applied N u")
    ax_t.plot(tr.t, tr.tau, color=plotting.COLORS[1], label=r"transmitted $\tau$")
    ax_t.set(xlabel="t [s]", ylabel="torque [N m]")
    ax_t.legend(loc="lower right")
    return plotting.save(fig, path)


def write(out: str | Path) -> list[Path]:
    """Run the lab experiments with the defaults and draw them into folder ``out``."""
    out = Path(out)
    chirp = chirp_run()
    return [draw_frfs(impulse_frfs(), out / "lab_fig11_impulse_frfs.png"),
            draw_chirp(chirp, out / "lab_fig12_13_down_chirp.png"),
            identification.draw(identification.identify(chirp.trace), out / "lab_fig12_13_identification.png"),
            draw_gravity(gravity_sweep(), out / "lab_fig14a_gravity.png"),
            draw_step(step_run(), out / "lab_fig14b_step.png")]
